# clutterseg-bench (per-stage times, pipelined throughput, RSS, allocations per frame) and the
# clutterseg_stage_bench Google Benchmark microbenchmarks. With -DCLUTTERSEG_PCL_BASELINE=ON
# the bench also runs PCL supervoxels + LCCP; PCL is linked only into clutterseg_bench_pcl and
# the bench executable, never into a product library.
if(NOT (TARGET clutterseg::pipeline AND TARGET clutterseg::io AND TARGET clutterseg::synth
        AND TARGET clutterseg::config))
  return()
endif()

set(_bench_dir ${CMAKE_CURRENT_LIST_DIR}/bench)

# Frame loading (PCD directory or synthetic renders) shared by both benchmarks.
add_library(clutterseg_bench_support STATIC ${_bench_dir}/frame_set.cc)
target_link_libraries(clutterseg_bench_support PUBLIC clutterseg::core clutterseg_options
                      PRIVATE clutterseg::io clutterseg::synth)

add_executable(clutterseg-bench ${_bench_dir}/clutterseg_bench.cc ${_bench_dir}/alloc_counter.cc)
target_link_libraries(clutterseg-bench PRIVATE clutterseg_bench_support clutterseg::pipeline
                      clutterseg::config CLI11::CLI11 nlohmann_json::nlohmann_json
                      Threads::Threads clutterseg_options)
if(CLUTTERSEG_SANITIZER)
  # The sanitizer runtime owns malloc/free: allocation counting is compiled out (reported n/a).
  target_compile_definitions(clutterseg-bench PRIVATE CLUTTERSEG_NO_ALLOC_COUNTER=1)
endif()

if(CLUTTERSEG_PCL_BASELINE)
  find_package(PCL 1.13 REQUIRED COMPONENTS common octree segmentation)
  add_library(clutterseg_bench_pcl STATIC ${_bench_dir}/pcl_lccp_runner.cc)
  # clutterseg_pcl_baseline (tools/pcl_baseline.cmake) provides BaselineParams; it is defined
  # after this file is included, which target_link_libraries allows.
  target_link_libraries(clutterseg_bench_pcl PUBLIC clutterseg::core clutterseg_pcl_baseline
                        clutterseg_options PRIVATE pcl_common pcl_octree pcl_segmentation)
  target_include_directories(clutterseg_bench_pcl SYSTEM PRIVATE ${PCL_INCLUDE_DIRS})
  target_compile_definitions(clutterseg_bench_pcl PRIVATE ${PCL_DEFINITIONS})
  target_link_libraries(clutterseg-bench PRIVATE clutterseg_bench_pcl)
  target_compile_definitions(clutterseg-bench PRIVATE CLUTTERSEG_BENCH_HAVE_PCL=1)
else()
  target_compile_definitions(clutterseg-bench PRIVATE CLUTTERSEG_BENCH_HAVE_PCL=0)
endif()

if(CLUTTERSEG_BUILD_BENCHMARKS)
  find_package(benchmark QUIET)
  if(benchmark_FOUND)
    add_executable(clutterseg_stage_bench ${_bench_dir}/stage_bench.cc)
    target_link_libraries(clutterseg_stage_bench PRIVATE clutterseg_bench_support
                          clutterseg::pipeline clutterseg::io benchmark::benchmark
                          clutterseg_options)
    target_compile_definitions(clutterseg_stage_bench PRIVATE
      CLUTTERSEG_DATA_DIR="${CLUTTERSEG_DATA_DIR}")
    if(TARGET clutterseg::daemon_lib)
      target_link_libraries(clutterseg_stage_bench PRIVATE clutterseg::daemon_lib)
      target_compile_definitions(clutterseg_stage_bench PRIVATE CLUTTERSEG_BENCH_HAVE_DAEMON=1)
    else()
      target_compile_definitions(clutterseg_stage_bench PRIVATE CLUTTERSEG_BENCH_HAVE_DAEMON=0)
    endif()
  else()
    message(STATUS "clutterseg: Google Benchmark not found; clutterseg_stage_bench skipped")
  endif()
endif()

if(CLUTTERSEG_BUILD_TESTS)
  # tools/ is added before the top level calls enable_testing(); enable it here for ctest.
  enable_testing()
  # Smoke test: two synthetic frames through every configuration; the JSON line must appear
  # and report objects found (PASS_REGULAR_EXPRESSION ignores the exit code, hence the
  # FAIL_REGULAR_EXPRESSION on the tool's error prefix).
  add_test(NAME clutterseg_bench_smoke
           COMMAND clutterseg-bench --synthetic 2 --repeat 1 --warmup 1 --threads 2)
  set_tests_properties(clutterseg_bench_smoke PROPERTIES
    TIMEOUT 300 LABELS "bench"
    PASS_REGULAR_EXPRESSION "\"frames\":2,\"repeat\":1.*\"objects_mean\":[1-9]"
    FAIL_REGULAR_EXPRESSION "clutterseg-bench: error")
endif()

if(CLUTTERSEG_BUILD_TESTS)
  # An unknown --set key is a bad command line: exit 2 naming the key (it was 1).
  add_test(NAME clutterseg_bench_unknown_key
           COMMAND sh -c "out=$(\"$0\" --synthetic 1 --set no.such=1 2>&1); rc=$?; echo \"$out\"; test $rc -eq 2 && echo \"$out\" | grep -q \"unknown key 'segmenter.no.such'\""
                   $<TARGET_FILE:clutterseg-bench>)
  set_tests_properties(clutterseg_bench_unknown_key PROPERTIES TIMEOUT 120 LABELS "bench")
endif()
