# Hardening (included at the end of CMakeLists.txt).
#
# For every model, a C driver (tests/c/fmu_driver.c) that loads the model's
# binary with dlopen and drives it through the FMI API with its own logger
# and a counting allocator, and one for its FMI 3.0 build
# (tests/c/fmu_driver3.c) and its FMI 1.0 build (tests/c/fmu_driver1.c);
# ctest runs the three per model. With
# CW_SANITIZE=ON the drivers and the FMUs are built with
# -fsanitize=address,undefined, the drivers run with LeakSanitizer on, and
# the pytest FMU suite (test fmu_tests) runs with the AddressSanitizer
# runtime preloaded into Python, which the instrumented FMUs need.

set(CW_SAN_ENV)
if(CW_SANITIZE)
  # Sanitizer reports are failures: abort on the first one.
  list(APPEND CW_SAN_ENV
       "UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1:abort_on_error=1"
       "ASAN_OPTIONS=detect_leaks=1:abort_on_error=1:strict_string_checks=1:detect_stack_use_after_return=1:check_initialization_order=1")
endif()

# One driver (tests/c/<source>) of one build (the library target `lib`)
# of a model, built against the model's variable table, as test `name`.
function(cw_fmu_driver name source model lib)
  set(gen_dir "${CMAKE_BINARY_DIR}/gen/${model}")
  add_executable(fmu_${name} "${CMAKE_SOURCE_DIR}/tests/c/${source}" "${gen_dir}/cw_vars.h")
  target_include_directories(fmu_${name} PRIVATE
    "${CMAKE_SOURCE_DIR}/tests/c" "${gen_dir}" "${RUNTIME_DIR}" "${FMI_HEADERS}")
  target_compile_options(fmu_${name} PRIVATE ${CW_WARNINGS} ${CW_SAN_FLAGS})
  target_link_options(fmu_${name} PRIVATE ${CW_SAN_FLAGS})
  target_link_libraries(fmu_${name} PRIVATE m ${CMAKE_DL_LIBS})
  add_dependencies(fmu_${name} ${lib})
  add_test(NAME ${name} COMMAND fmu_${name} "$<TARGET_FILE:${lib}>")
  if(CW_SAN_ENV)
    set_tests_properties(${name} PROPERTIES ENVIRONMENT "${CW_SAN_ENV}")
  endif()
endfunction()

foreach(table ${MODEL_TABLES})
  get_filename_component(model_dir "${table}" DIRECTORY)
  get_filename_component(model "${model_dir}" NAME)
  cw_fmu_driver(driver_${model} fmu_driver.c ${model} ${model})
  # The FMI 3.0 and FMI 1.0 builds of the same model (the fmi3 and fmi1 faces).
  cw_fmu_driver(driver3_${model} fmu_driver3.c ${model} ${model}_fmi3)
  cw_fmu_driver(driver1_${model} fmu_driver1.c ${model} ${model}_fmi1)
endforeach()

if(CW_SANITIZE)
  # Python itself is not instrumented: the runtime must be loaded first,
  # and Python's own allocations at exit are no leaks of ours (the drivers
  # above run with leak detection on for the FMUs).
  execute_process(COMMAND "${CMAKE_C_COMPILER}" -print-file-name=libasan.so
                  OUTPUT_VARIABLE CW_ASAN_RUNTIME OUTPUT_STRIP_TRAILING_WHITESPACE)
  if(NOT EXISTS "${CW_ASAN_RUNTIME}")
    message(FATAL_ERROR "CW_SANITIZE: '${CMAKE_C_COMPILER} -print-file-name=libasan.so' "
                        "gave '${CW_ASAN_RUNTIME}', which does not exist.")
  endif()
  # tests/c/asan_fmpy.py makes fmpy hand the FMUs the sanitizer's
  # calloc/free instead of libc's, so that the FMUs' heap is checked too.
  # No quarantine: test_states_are_freed measures the process's RSS over
  # 1e5 get/free cycles, and quarantined blocks would count as growth
  # (the drivers above keep the default quarantine).
  set_property(TEST fmu_tests APPEND PROPERTY ENVIRONMENT
    "LD_PRELOAD=${CW_ASAN_RUNTIME}"
    "ASAN_OPTIONS=detect_leaks=0:abort_on_error=1:quarantine_size_mb=0"
    "UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1:abort_on_error=1"
    "PYTHONPATH=${CMAKE_SOURCE_DIR}/tests/c"
    "PYTEST_ADDOPTS=-p asan_fmpy")
endif()

if(CW_SANITIZE)
  # The master's compiled core under the sanitizers: the engine comparison
  # (Python master against the core, step by step) on the instrumented
  # FMUs, with the instrumented core loaded instead of the checkout's lib/.
  # The whole-scene cases are left out: they draw plots, and matplotlib's
  # own uninstrumented C++ aborts under the preloaded runtime.
  add_test(NAME core_tests
           COMMAND "${Python3_EXECUTABLE}" -m pytest -q -p no:cacheprovider "${CMAKE_SOURCE_DIR}/tests/test_compiled.py"
                   -k "not same_files and not bad_input"
           WORKING_DIRECTORY "${CMAKE_SOURCE_DIR}")
  set_tests_properties(core_tests PROPERTIES ENVIRONMENT
    "LD_PRELOAD=${CW_ASAN_RUNTIME};ASAN_OPTIONS=detect_leaks=0:abort_on_error=1;UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1:abort_on_error=1;PYTHONPATH=${CMAKE_SOURCE_DIR}/tests/c;PYTEST_ADDOPTS=-p asan_fmpy;CLOCKWORK_CORE_LIB=${CW_LIB_DIR}/libcw_master.so;CLOCKWORK_FMU_DIR=${CW_FMU_DIR};CW_FMU_DIR=${CW_FMU_DIR};CLOCKWORK_CACHE=off")
  # The core's Model Exchange wrapper (cw_me.c, with cw_rk.c and CVode) on
  # the instrumented Model Exchange test FMUs; the scenes are left out (plots).
  add_test(NAME me_tests
           COMMAND "${Python3_EXECUTABLE}" -m pytest -q -p no:cacheprovider
                   "${CMAKE_SOURCE_DIR}/tests/test_model_exchange.py" -k "not scene and not ssp and not info"
           WORKING_DIRECTORY "${CMAKE_SOURCE_DIR}")
  set_tests_properties(me_tests PROPERTIES ENVIRONMENT
    "LD_PRELOAD=${CW_ASAN_RUNTIME};ASAN_OPTIONS=detect_leaks=0:abort_on_error=1;UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1:abort_on_error=1;PYTHONPATH=${CMAKE_SOURCE_DIR}/tests/c;PYTEST_ADDOPTS=-p asan_fmpy;CLOCKWORK_CORE_LIB=${CW_LIB_DIR}/libcw_master.so;CLOCKWORK_FMU_DIR=${CW_FMU_DIR};CW_FMU_DIR=${CW_FMU_DIR};CW_TEST_FMU_DIR=${CMAKE_BINARY_DIR}/test-fmus;CLOCKWORK_CACHE=off")
endif()
