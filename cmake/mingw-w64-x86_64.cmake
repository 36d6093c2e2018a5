# Toolchain file: 64-bit Windows DLLs with Debian's mingw-w64
# (apt-get install mingw-w64). Used by the Windows build the main build
# runs in build/win64 (cmake/cross.cmake); by hand:
#   cmake -S . -B build-win64 -G Ninja -DCMAKE_TOOLCHAIN_FILE=cmake/mingw-w64-x86_64.cmake
set(CMAKE_SYSTEM_NAME Windows)
set(CMAKE_SYSTEM_PROCESSOR x86_64)
set(CW_CROSS_PREFIX x86_64-w64-mingw32)
set(CMAKE_C_COMPILER ${CW_CROSS_PREFIX}-gcc)
set(CMAKE_RC_COMPILER ${CW_CROSS_PREFIX}-windres)
set(CMAKE_FIND_ROOT_PATH /usr/${CW_CROSS_PREFIX})
# Programs (Python, for fmugen) from the build machine; libraries and
# headers from the target's root only.
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
