# stagefit_library(NAME layer DEPS ...): one static library per layer folder, built from every .cc in
# src/<layer>/, namespace stagefit::<layer>, headers in include/stagefit/<layer>/.
function(stagefit_library)
  cmake_parse_arguments(ARG "" "NAME" "DEPS" ${ARGN})
  file(GLOB sources CONFIGURE_DEPENDS ${CMAKE_CURRENT_SOURCE_DIR}/*.cc)
  add_library(stagefit_${ARG_NAME} STATIC ${sources})
  target_include_directories(stagefit_${ARG_NAME} PUBLIC ${PROJECT_SOURCE_DIR}/include)
  target_link_libraries(stagefit_${ARG_NAME} PUBLIC ${ARG_DEPS})
  add_library(stagefit::${ARG_NAME} ALIAS stagefit_${ARG_NAME})
endfunction()

# stagefit_test(path/to/foo_test.cc DEPS ...): one test program per test file, registered with CTest.
function(stagefit_test source)
  cmake_parse_arguments(ARG "" "" "DEPS" ${ARGN})
  get_filename_component(name ${source} NAME_WE)
  add_executable(${name} ${source})
  target_link_libraries(${name} PRIVATE ${ARG_DEPS} GTest::gtest GTest::gtest_main)
  target_compile_definitions(${name} PRIVATE
    STAGEFIT_SOURCE_DIR="${PROJECT_SOURCE_DIR}"
    STAGEFIT_SHARED_DATA_DIR="${PROJECT_SOURCE_DIR}/../shared/data"
    STAGEFIT_BINARY="$<TARGET_FILE:stagefit>")
  gtest_discover_tests(${name} DISCOVERY_TIMEOUT 60 PROPERTIES LABELS unit)
endfunction()

# stagefit_layer_tests(layer [DEPS ...]): every tests/<layer>/*_test.cc becomes a test program linked with
# stagefit::<layer> (and DEPS).
function(stagefit_layer_tests layer)
  cmake_parse_arguments(ARG "" "" "DEPS" ${ARGN})
  file(GLOB tests CONFIGURE_DEPENDS ${CMAKE_CURRENT_SOURCE_DIR}/*_test.cc)
  foreach(t ${tests})
    stagefit_test(${t} DEPS stagefit::${layer} ${ARG_DEPS})
  endforeach()
endfunction()
