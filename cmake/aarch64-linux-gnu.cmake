# Toolchain file: Linux on 64-bit Arm (FMI 3.0 aarch64-linux) with Debian's
# cross compiler (apt-get install gcc-aarch64-linux-gnu); its programs run
# on x86-64 under qemu-user (qemu-aarch64 -L /usr/aarch64-linux-gnu).
# Used by the cross build the main build runs in build/aarch64-linux
# (cmake/platforms.cmake, cmake/cross.cmake).
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)
set(CW_CROSS_PREFIX aarch64-linux-gnu)
set(CMAKE_C_COMPILER ${CW_CROSS_PREFIX}-gcc)
set(CMAKE_FIND_ROOT_PATH /usr/${CW_CROSS_PREFIX})
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
