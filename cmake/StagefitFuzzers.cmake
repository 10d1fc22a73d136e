# STAGEFIT_BUILD_FUZZERS: the libFuzzer programs of tests/fuzz/, one per file reader, built with clang,
# AddressSanitizer and UndefinedBehaviorSanitizer. Only the libraries the readers need are built (no
# CLI, tests or benchmarks); they get the sanitizers and libFuzzer's coverage instrumentation too.
# scripts/fuzz.sh configures, builds and runs them.
if(NOT CMAKE_CXX_COMPILER_ID MATCHES "Clang")
  message(FATAL_ERROR
    "STAGEFIT_BUILD_FUZZERS needs clang (libFuzzer), but the C++ compiler is ${CMAKE_CXX_COMPILER_ID} "
    "(${CMAKE_CXX_COMPILER}). Configure a fresh build folder with CC=clang CXX=clang++, as "
    "scripts/fuzz.sh does.")
endif()

include(CheckCXXSourceCompiles)
set(CMAKE_REQUIRED_FLAGS "-fsanitize=fuzzer,address,undefined")
set(CMAKE_REQUIRED_LINK_OPTIONS "-fsanitize=fuzzer,address,undefined")
check_cxx_source_compiles([[
#include <cstddef>
#include <cstdint>
extern "C" int LLVMFuzzerTestOneInput(const uint8_t*, size_t) { return 0; }
]] STAGEFIT_HAVE_LIBFUZZER)
unset(CMAKE_REQUIRED_FLAGS)
unset(CMAKE_REQUIRED_LINK_OPTIONS)
if(NOT STAGEFIT_HAVE_LIBFUZZER)
  message(FATAL_ERROR
    "STAGEFIT_BUILD_FUZZERS: ${CMAKE_CXX_COMPILER} cannot link -fsanitize=fuzzer,address,undefined; "
    "install the compiler runtime (Debian: libclang-rt-14-dev for clang 14).")
endif()

# -O1 (libFuzzer's advice): fast enough to fuzz, quicker to build than -O3; assertions stay on.
set(CMAKE_CXX_FLAGS_RELEASE "-O1")
add_compile_options(-fsanitize=fuzzer-no-link,address,undefined -fno-sanitize-recover=undefined
                    -fno-omit-frame-pointer -gline-tables-only)
add_link_options(-fsanitize=address,undefined)

# stagefit_fuzzer(name DEPS ...): the libFuzzer program tests/fuzz/<name>.cc linked with DEPS.
function(stagefit_fuzzer name)
  cmake_parse_arguments(ARG "" "" "DEPS" ${ARGN})
  add_executable(${name} ${CMAKE_CURRENT_SOURCE_DIR}/${name}.cc)
  target_link_libraries(${name} PRIVATE ${ARG_DEPS})
  target_link_options(${name} PRIVATE -fsanitize=fuzzer)
  set_target_properties(${name} PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${PROJECT_BINARY_DIR}/fuzz)
endfunction()

# The reader layers and what they depend on, in dependency order.
foreach(layer common kinematics model response measurement disturbance)
  add_subdirectory(${PROJECT_SOURCE_DIR}/src/${layer} ${PROJECT_BINARY_DIR}/src/${layer})
endforeach()
add_subdirectory(${PROJECT_SOURCE_DIR}/tests/fuzz ${PROJECT_BINARY_DIR}/tests/fuzz)
