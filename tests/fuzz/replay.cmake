# The normal test build's part of tests/fuzz/: each libFuzzer program's LLVMFuzzerTestOneInput linked
# with replay_main.cc instead of libFuzzer, and a CTest test FuzzReplay.<program> that runs it on the
# program's seeds (corpus/) and stored crash inputs (regressions/). v7.3 .mat inputs are replayed too
# (STAGEFIT_FUZZ_V73=1, as `scripts/fuzz.sh --replay` does). Fuzzing itself (clang, libFuzzer, new
# inputs) is scripts/fuzz.sh.
set(fuzz_dir ${PROJECT_SOURCE_DIR}/tests/fuzz)
foreach(pair model_file_fuzz:model mat_measurement_fuzz:measurement raw_hammer_fuzz:measurement
             uff_measurement_fuzz:measurement csv_measurement_fuzz:measurement record_csv_fuzz:disturbance)
  string(REPLACE ":" ";" pair ${pair})
  list(GET pair 0 program)
  list(GET pair 1 layer)
  add_executable(${program}_replay ${fuzz_dir}/${program}.cc ${fuzz_dir}/replay_main.cc)
  target_link_libraries(${program}_replay PRIVATE stagefit::${layer})
  set(inputs ${fuzz_dir}/corpus/${program})
  if(EXISTS ${fuzz_dir}/regressions/${program})
    list(APPEND inputs ${fuzz_dir}/regressions/${program})
  endif()
  add_test(NAME FuzzReplay.${program} COMMAND ${program}_replay ${inputs})
  set_tests_properties(FuzzReplay.${program} PROPERTIES LABELS unit ENVIRONMENT STAGEFIT_FUZZ_V73=1)
endforeach()
