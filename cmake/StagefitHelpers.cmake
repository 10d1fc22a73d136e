# Precompiled headers (STAGEFIT_PCH): the external and standard headers most files include are parsed
# once per build instead of once per file, one header for the libraries and the CLI, one with
# GoogleTest added for the test programs. A file's own includes still name what it uses: the
# precompiled header only makes them cheap.
set(STAGEFIT_PCH_HEADERS
  <algorithm> <array> <cmath> <complex> <cstdint> <cstdio> <filesystem> <fstream> <functional>
  <limits> <map> <memory> <optional> <random> <set> <sstream> <string> <string_view> <utility>
  <vector> <Eigen/Dense> <nlohmann/json.hpp>)

# stagefit_use_pch(target [TESTS]): gives target the shared precompiled header, compiled once by a
# target of its own (stagefit_pch or stagefit_test_pch) and reused by every library or test program.
function(stagefit_use_pch target)
  cmake_parse_arguments(ARG "TESTS" "" "" ${ARGN})
  if(NOT STAGEFIT_PCH)
    return()
  endif()
  if(ARG_TESTS)
    set(owner stagefit_test_pch)
  else()
    set(owner stagefit_pch)
  endif()
  if(NOT TARGET ${owner})
    set(stub ${PROJECT_BINARY_DIR}/${owner}.cc)
    if(NOT EXISTS ${stub})
      file(WRITE ${stub} "// Compiles the shared precompiled header (cmake/StagefitHelpers.cmake).\n")
    endif()
    add_library(${owner} STATIC ${stub})
    target_link_libraries(${owner} PRIVATE Eigen3::Eigen nlohmann_json::nlohmann_json)
    set(headers ${STAGEFIT_PCH_HEADERS})
    if(ARG_TESTS)
      target_link_libraries(${owner} PRIVATE GTest::gtest)
      list(APPEND headers <gtest/gtest.h>)
      stagefit_test_definitions(${owner})
    endif()
    target_precompile_headers(${owner} PRIVATE ${headers})
  endif()
  target_precompile_headers(${target} REUSE_FROM ${owner})
endfunction()

# The definitions every test program is compiled with (the precompiled header's too, so it matches).
function(stagefit_test_definitions target)
  target_compile_definitions(${target} PRIVATE
    STAGEFIT_SOURCE_DIR="${PROJECT_SOURCE_DIR}"
    STAGEFIT_SHARED_DATA_DIR="${PROJECT_SOURCE_DIR}/../shared/data"
    STAGEFIT_BINARY="$<TARGET_FILE:stagefit>")
endfunction()

# stagefit_use_unity_build(target [BATCH n]) (STAGEFIT_UNITY_BUILD): target's sources compiled in
# batches of n (default 8) per translation unit, so that the Eigen and Ceres templates they share are instantiated and optimised
# once per batch instead of once per file (about 40 % less compile time for src/). Names in a file's
# anonymous namespace are then visible to the other files of its batch: two helpers of the same name
# and signature fail to compile, so each file's helpers keep their own names.
# The files of the fits' inner loops (STAGEFIT_HOT_SOURCES) are compiled on their own: in a batch, GCC
# inlines less of them (a loop 5 % slower).
set(STAGEFIT_HOT_SOURCES frf_evaluator.cc stiffness_update.cc residuals.cc least_squares.cc effect_problem.cc)
function(stagefit_use_unity_build target)
  cmake_parse_arguments(ARG "" "BATCH" "" ${ARGN})
  if(NOT DEFINED ARG_BATCH)
    set(ARG_BATCH 8)
  endif()
  if(STAGEFIT_UNITY_BUILD)
    set_target_properties(${target} PROPERTIES UNITY_BUILD ON UNITY_BUILD_BATCH_SIZE ${ARG_BATCH})
    get_target_property(sources ${target} SOURCES)
    foreach(source ${sources})
      get_filename_component(name ${source} NAME)
      if(name IN_LIST STAGEFIT_HOT_SOURCES)
        set_source_files_properties(${source} PROPERTIES SKIP_UNITY_BUILD_INCLUSION ON)
      endif()
    endforeach()
  endif()
endfunction()

# stagefit_library(NAME layer DEPS ...): one static library per layer folder, built from every .cc in
# src/<layer>/, namespace stagefit::<layer>, headers in include/stagefit/<layer>/.
function(stagefit_library)
  cmake_parse_arguments(ARG "" "NAME" "DEPS" ${ARGN})
  file(GLOB sources CONFIGURE_DEPENDS ${CMAKE_CURRENT_SOURCE_DIR}/*.cc)
  add_library(stagefit_${ARG_NAME} STATIC ${sources})
  target_include_directories(stagefit_${ARG_NAME} PUBLIC ${PROJECT_SOURCE_DIR}/include)
  target_link_libraries(stagefit_${ARG_NAME} PUBLIC ${ARG_DEPS})
  add_library(stagefit::${ARG_NAME} ALIAS stagefit_${ARG_NAME})
  stagefit_use_pch(stagefit_${ARG_NAME})
  stagefit_use_unity_build(stagefit_${ARG_NAME})
endfunction()

# stagefit_test(name SOURCES a_test.cc ... [COST c] DEPS ...): one test program of the given test files,
# registered with CTest test by test (each test still runs in its own process). COST (CTest's property,
# default 0) orders a fresh build folder's first run, which has no timings yet: higher first. The
# programs whose tests run diagnoses and loops (10-110 s each) set it, so that a parallel run does not
# end with one of them alone. The files are compiled in batches of four (stagefit_use_unity_build), as
# the libraries' are: GoogleTest's and Eigen's templates are instantiated once per batch, and one
# program per layer is linked instead of one per file (a fresh build with the tests: 781 s of compiler
# and linker time against 1059 s with a program per file). A test file's helpers in its anonymous
# namespace are then seen by the other files of its batch, so each file's helpers keep their own names,
# as in src/.
function(stagefit_test name)
  cmake_parse_arguments(ARG "" "COST" "SOURCES;DEPS" ${ARGN})
  if(NOT DEFINED ARG_COST)
    set(ARG_COST 0)
  endif()
  add_executable(${name} ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE ${ARG_DEPS} GTest::gtest GTest::gtest_main)
  stagefit_test_definitions(${name})
  stagefit_use_pch(${name} TESTS)
  stagefit_use_unity_build(${name} BATCH 4)
  gtest_discover_tests(${name} DISCOVERY_TIMEOUT 60 PROPERTIES LABELS unit COST ${ARG_COST})
endfunction()

# stagefit_fuzzer(name DEPS ...) in the test build: the fuzz program tests/fuzz/<name>.cc linked with
# tests/fuzz/replay_main.cc instead of libFuzzer, and a CTest test FuzzReplay.<name> that runs it on the
# program's seeds and stored crash inputs, v7.3 .mat inputs too (STAGEFIT_FUZZ_V73=1, as
# `scripts/fuzz.sh --replay`). The fuzz build defines its own (cmake/StagefitFuzzers.cmake).
function(stagefit_fuzzer name)
  cmake_parse_arguments(ARG "" "" "DEPS" ${ARGN})
  add_executable(${name}_replay ${CMAKE_CURRENT_SOURCE_DIR}/${name}.cc ${CMAKE_CURRENT_SOURCE_DIR}/replay_main.cc)
  target_link_libraries(${name}_replay PRIVATE ${ARG_DEPS})
  set(inputs ${CMAKE_CURRENT_SOURCE_DIR}/corpus/${name})
  if(EXISTS ${CMAKE_CURRENT_SOURCE_DIR}/regressions/${name})
    list(APPEND inputs ${CMAKE_CURRENT_SOURCE_DIR}/regressions/${name})
  endif()
  add_test(NAME FuzzReplay.${name} COMMAND ${name}_replay ${inputs})
  set_tests_properties(FuzzReplay.${name} PROPERTIES LABELS unit ENVIRONMENT STAGEFIT_FUZZ_V73=1)
endfunction()

# stagefit_layer_tests(layer [COST c] [DEPS ...]): the tests/<layer>/*_test.cc are one test program,
# <layer>_tests, linked with stagefit::<layer> (and DEPS); COST as stagefit_test's (its default when not
# given).
function(stagefit_layer_tests layer)
  cmake_parse_arguments(ARG "" "COST" "DEPS" ${ARGN})
  file(GLOB tests CONFIGURE_DEPENDS ${CMAKE_CURRENT_SOURCE_DIR}/*_test.cc)
  stagefit_test(${layer}_tests SOURCES ${tests} COST ${ARG_COST} DEPS stagefit::${layer} ${ARG_DEPS})
endfunction()
