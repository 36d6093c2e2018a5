# The cross build (included by CMakeLists.txt when a toolchain file from
# cmake/ is given): the bundled models' binaries for another platform, from
# the same model.c, runtime and generated variable tables as the native
# build, and the platform check harness (tools/platcheck/harness.c). The
# native build runs this build in build/<platform>/ and packs its binaries
# into the FMUs (cmake/platforms.cmake); nothing here writes an FMU.
#
#   <build>/fmi2/<Name>.dll   FMI 2.0, binaries/win64 (Windows only)
#   <build>/fmi3/<Name>.<ext> FMI 3.0, binaries/<platform tuple>
#   <build>/platcheck[.exe]

if(CMAKE_SYSTEM_NAME STREQUAL "Windows" AND CMAKE_SYSTEM_PROCESSOR STREQUAL "x86_64")
  set(cross_fmi2 ON)  # FMI 2.0 names 64-bit Windows win64
elseif(CMAKE_SYSTEM_NAME STREQUAL "Linux" AND CMAKE_SYSTEM_PROCESSOR STREQUAL "aarch64")
  set(cross_fmi2 OFF)  # FMI 2.0 has no platform folder for it
else()
  message(FATAL_ERROR "cmake/cross.cmake: no FMU platform for ${CMAKE_SYSTEM_NAME} ${CMAKE_SYSTEM_PROCESSOR}")
endif()

set(cross_defs)
set(cross_copts)
set(cross_link)
if(WIN32)
  # C99 printf (%zu in the runtime's messages) from mingw-w64's own stdio
  # rather than msvcrt's; libgcc and winpthread linked in, so that a DLL
  # needs only Windows' own DLLs; no link time in the PE header, so that a
  # rebuild gives the same bytes (tests/test_reproducible.py); no symbol
  # table (a third of the DLL), the exports stay.
  set(cross_defs __USE_MINGW_ANSI_STDIO=1)
  set(cross_link -static -static-libgcc -Wl,--no-insert-timestamp -s)
else()
  # No fused multiply-add: GCC contracts a * b + c on Arm (not on x86-64's
  # baseline), which would round otherwise than the x86-64 build.
  set(cross_copts -ffp-contract=off)
  set(cross_link -static-libgcc)
endif()

file(GLOB cross_tables CONFIGURE_DEPENDS "${CMAKE_SOURCE_DIR}/src_c/models/*/model.toml")
foreach(table ${cross_tables})
  get_filename_component(model_dir "${table}" DIRECTORY)
  get_filename_component(model "${model_dir}" NAME)
  set(gen_dir "${CMAKE_BINARY_DIR}/gen/${model}")
  # fmugen writes every generated file; this build uses only cw_vars.h.
  add_custom_command(
    OUTPUT "${gen_dir}/cw_vars.h"
    COMMAND "${Python3_EXECUTABLE}" "${FMUGEN}" "${model_dir}" "${gen_dir}"
    DEPENDS "${table}" "${model_dir}/model.c" ${FMUGEN_DEPENDS}
    COMMENT "Generating the variable table of ${model}")
  set(versions 3)
  if(cross_fmi2)
    set(versions 2 3)
  endif()
  foreach(v ${versions})
    set(target ${model}_fmi${v})
    add_library(${target} SHARED ${RUNTIME_SOURCES${v}} "${model_dir}/model.c" "${gen_dir}/cw_vars.h")
    # A DLL is a RUNTIME output, a .so a LIBRARY output; the import library
    # (lib<Name>.dll.a) goes aside.
    set_target_properties(${target} PROPERTIES PREFIX "" OUTPUT_NAME "${model}"
                          RUNTIME_OUTPUT_DIRECTORY "${CMAKE_BINARY_DIR}/fmi${v}"
                          LIBRARY_OUTPUT_DIRECTORY "${CMAKE_BINARY_DIR}/fmi${v}"
                          ARCHIVE_OUTPUT_DIRECTORY "${CMAKE_BINARY_DIR}/implib${v}")
    target_include_directories(${target} PRIVATE "${RUNTIME_DIR}" "${gen_dir}" "${FMI_HEADERS}")
    target_compile_definitions(${target} PRIVATE ${cross_defs})
    target_compile_options(${target} PRIVATE ${CW_WARNINGS} ${cross_copts})
    target_link_options(${target} PRIVATE ${cross_link})
    if(NOT WIN32)
      target_link_libraries(${target} PRIVATE m)
    endif()
  endforeach()
endforeach()

add_executable(platcheck "${CMAKE_SOURCE_DIR}/tools/platcheck/harness.c")
target_include_directories(platcheck PRIVATE "${FMI_HEADERS}")
target_compile_definitions(platcheck PRIVATE ${cross_defs})
target_compile_options(platcheck PRIVATE ${CW_WARNINGS} ${cross_copts})
if(WIN32)
  target_link_options(platcheck PRIVATE ${cross_link})
else()  # run with the target's glibc: qemu-aarch64 -L /usr/aarch64-linux-gnu
  target_link_libraries(platcheck PRIVATE m ${CMAKE_DL_LIBS})
endif()

# The front of an exported system FMU (clockwork export-fmu), for Windows:
# src_c/export/cw_system.c with the compiled core, whatever files the core
# is in, but its crash guard and logger (cw_guard.c, cw_log.c: POSIX; the
# front has a stand-in). The native build copies it to lib/ beside the Linux one.
if(WIN32)
  file(GLOB cw_core_sources CONFIGURE_DEPENDS "${CMAKE_SOURCE_DIR}/src_c/master/*.c")
  list(FILTER cw_core_sources EXCLUDE REGEX "/cw_(guard|log)\\.c$")
  add_library(cw_system SHARED "${CMAKE_SOURCE_DIR}/src_c/export/cw_system.c" ${cw_core_sources}
              "${RUNTIME_DIR}/cw_rk.c")
  set_target_properties(cw_system PROPERTIES PREFIX "" RUNTIME_OUTPUT_DIRECTORY "${CMAKE_BINARY_DIR}/export"
                        ARCHIVE_OUTPUT_DIRECTORY "${CMAKE_BINARY_DIR}/implib-export")
  target_include_directories(cw_system PRIVATE "${RUNTIME_DIR}" "${CMAKE_SOURCE_DIR}/src_c/master" "${FMI_HEADERS}")
  target_compile_definitions(cw_system PRIVATE ${cross_defs} CW_RK_MAXN=256)
  target_compile_options(cw_system PRIVATE ${CW_WARNINGS} -ffp-contract=off -fno-fast-math)
  target_link_options(cw_system PRIVATE ${cross_link})
  target_link_libraries(cw_system PRIVATE pthread)
endif()
