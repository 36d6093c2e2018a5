# Binaries for other platforms in the bundled FMUs (included by
# CMakeLists.txt in the native build). Each platform is a cross build of
# this same tree with a toolchain file from cmake/ (cmake/cross.cmake says
# what it builds), run by the native build as an external project in
# build/<platform>/; the FMUs' packaging copies its binaries in beside the
# Linux ones. Only the bundled models (src_c/models) get them.
#
#   CW_WINDOWS  ON: Windows DLLs (FMI 2.0 win64, FMI 3.0 x86_64-windows)
#               with Debian's mingw-w64, an error without it; OFF: none;
#               AUTO (default): ON where x86_64-w64-mingw32-gcc is found.
#   CW_AARCH64  the same for Linux on 64-bit Arm (FMI 3.0 aarch64-linux
#               only: FMI 2.0 names no such platform) with Debian's
#               gcc-aarch64-linux-gnu.
#
# Sets CW_FMI2_PLATFORMS / CW_FMI3_PLATFORMS (the bundled FMUs' binaries
# folders, the native one first, for their documentation), and per cross
# platform P the target cross_<P>, CW_CROSS_DIR_<P> (its build folder),
# CW_CROSS_EXT_<P> (.dll, .so) and CW_CROSS_FMI2_<P> (its FMI 2.0 folder,
# empty for none); cw_cross_packaging() turns them into packaging steps.

include(ExternalProject)

set(CW_WINDOWS AUTO CACHE STRING "Windows DLLs in the bundled FMUs: ON, OFF or AUTO (ON where mingw-w64 is found)")
set_property(CACHE CW_WINDOWS PROPERTY STRINGS AUTO ON OFF)
set(CW_AARCH64 AUTO CACHE STRING "aarch64-linux binaries in the bundled FMI 3.0 FMUs: ON, OFF or AUTO")
set_property(CACHE CW_AARCH64 PROPERTY STRINGS AUTO ON OFF)

set(CW_FMI2_PLATFORMS linux64)
set(CW_FMI3_PLATFORMS x86_64-linux)
set(CW_CROSS_PLATFORMS)

# One cross build: platform P (its FMI 3.0 folder name), toolchain file T,
# FMI 2.0 folder name F2 (empty: no FMI 2.0 build), binary suffix EXT.
function(cw_cross_platform P T F2 EXT)
  set(dir "${CMAKE_BINARY_DIR}/${P}")
  set(byproducts)
  foreach(table ${MODEL_TABLES})
    get_filename_component(model_dir "${table}" DIRECTORY)
    get_filename_component(model "${model_dir}" NAME)
    list(APPEND byproducts "${dir}/fmi3/${model}${EXT}")
    if(F2)
      list(APPEND byproducts "${dir}/fmi2/${model}${EXT}")
    endif()
  endforeach()
  ExternalProject_Add(cross_${P}
    SOURCE_DIR "${CMAKE_SOURCE_DIR}"
    BINARY_DIR "${dir}"
    CMAKE_GENERATOR "${CMAKE_GENERATOR}"
    CMAKE_ARGS "-DCMAKE_TOOLCHAIN_FILE=${CMAKE_SOURCE_DIR}/cmake/${T}"
               "-DCMAKE_BUILD_TYPE=${CMAKE_BUILD_TYPE}"
               "-DPython3_EXECUTABLE=${Python3_EXECUTABLE}"
    # Its own ninja decides what is out of date (model.c, the runtime).
    BUILD_ALWAYS ON
    BUILD_BYPRODUCTS ${byproducts}
    INSTALL_COMMAND ""
    # Its output only on failure, as for the native targets.
    LOG_CONFIGURE ON LOG_BUILD ON LOG_OUTPUT_ON_FAILURE ON)
  set(CW_CROSS_DIR_${P} "${dir}" PARENT_SCOPE)
  set(CW_CROSS_EXT_${P} "${EXT}" PARENT_SCOPE)
  set(CW_CROSS_FMI2_${P} "${F2}" PARENT_SCOPE)
  set(CW_CROSS_PLATFORMS ${CW_CROSS_PLATFORMS} ${P} PARENT_SCOPE)
  set(CW_FMI3_PLATFORMS ${CW_FMI3_PLATFORMS} ${P} PARENT_SCOPE)
  if(F2)
    set(CW_FMI2_PLATFORMS ${CW_FMI2_PLATFORMS} ${F2} PARENT_SCOPE)
  endif()
endfunction()

# Whether to build for a platform: option OPT (AUTO, ON, OFF) and its
# compiler GCC, Debian's package DEB; the answer in OUT.
function(cw_want_platform OPT GCC DEB OUT)
  set(want OFF)
  if(NOT CW_SANITIZE)  # the sanitizer build checks the Linux binaries only
    find_program(CW_GCC_${OPT} ${GCC})
    if(${OPT} STREQUAL "AUTO")
      if(CW_GCC_${OPT})
        set(want ON)
      else()
        message(STATUS "No ${GCC} (Debian: ${DEB}): ${OPT} is off")
      endif()
    elseif(${OPT})
      if(NOT CW_GCC_${OPT})
        message(FATAL_ERROR "${OPT}=ON needs ${GCC} (Debian: apt-get install ${DEB})")
      endif()
      set(want ON)
    endif()
  endif()
  set(${OUT} ${want} PARENT_SCOPE)
endfunction()

cw_want_platform(CW_WINDOWS x86_64-w64-mingw32-gcc mingw-w64 cw_windows)
if(cw_windows)
  cw_cross_platform(x86_64-windows mingw-w64-x86_64.cmake win64 .dll)
endif()
cw_want_platform(CW_AARCH64 aarch64-linux-gnu-gcc gcc-aarch64-linux-gnu cw_aarch64)
if(cw_aarch64)
  cw_cross_platform(aarch64-linux aarch64-linux-gnu.cmake "" .so)
endif()

# The packaging commands of model M's FMI version V (2 or 3) build in the
# stage folder S: OUT_DIRS, the binaries folders to make; OUT_COPY, the
# copy commands; OUT_DEPS, the binaries and targets they need.
function(cw_cross_packaging M V S OUT_DIRS OUT_COPY OUT_DEPS)
  set(dirs)
  set(copy)
  set(deps)
  foreach(P ${CW_CROSS_PLATFORMS})
    set(folder "${P}")
    if(V EQUAL 2)
      set(folder "${CW_CROSS_FMI2_${P}}")
    endif()
    if(folder)
      set(bin "${CW_CROSS_DIR_${P}}/fmi${V}/${M}${CW_CROSS_EXT_${P}}")
      list(APPEND dirs "${S}/binaries/${folder}")
      list(APPEND copy COMMAND "${CMAKE_COMMAND}" -E copy "${bin}" "${S}/binaries/${folder}/${M}${CW_CROSS_EXT_${P}}")
      list(APPEND deps "${bin}" cross_${P})
    endif()
  endforeach()
  set(${OUT_DIRS} ${dirs} PARENT_SCOPE)
  set(${OUT_COPY} ${copy} PARENT_SCOPE)
  set(${OUT_DEPS} ${deps} PARENT_SCOPE)
endfunction()
