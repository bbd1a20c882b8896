# PCL reference baselines (supervoxels + LCCP, organized planes + Euclidean clusters).
# Optional: only with -DCLUTTERSEG_PCL_BASELINE=ON. PCL is linked into these targets only.
if(NOT CLUTTERSEG_PCL_BASELINE)
  return()
endif()

find_package(PCL 1.13 REQUIRED COMPONENTS common io segmentation features search kdtree filters)

# All PCL-heavy code lives in one translation unit to keep compile time down.
add_library(clutterseg_pcl_baseline STATIC ${CMAKE_CURRENT_LIST_DIR}/pcl_baseline/pcl_baseline.cc)
target_link_libraries(clutterseg_pcl_baseline PUBLIC clutterseg_options
                      PRIVATE pcl_common pcl_octree pcl_io pcl_segmentation pcl_features pcl_search
                              pcl_kdtree pcl_filters)
target_include_directories(clutterseg_pcl_baseline SYSTEM PRIVATE ${PCL_INCLUDE_DIRS})
target_compile_definitions(clutterseg_pcl_baseline PRIVATE ${PCL_DEFINITIONS})

add_executable(clutterseg-pcl-baseline ${CMAKE_CURRENT_LIST_DIR}/pcl_baseline/main.cc)
target_link_libraries(clutterseg-pcl-baseline PRIVATE clutterseg_pcl_baseline clutterseg::core CLI11::CLI11
                      pcl_common)
target_include_directories(clutterseg-pcl-baseline SYSTEM PRIVATE ${PCL_INCLUDE_DIRS})

if(CLUTTERSEG_BUILD_TESTS)
  find_package(GTest REQUIRED)
  include(${PROJECT_SOURCE_DIR}/tools/cmake/clutterseg_gtest.cmake)
  add_executable(pcl_baseline_test ${CMAKE_CURRENT_LIST_DIR}/pcl_baseline/pcl_baseline_test.cc)
  target_link_libraries(pcl_baseline_test PRIVATE clutterseg_pcl_baseline clutterseg_testing
                        GTest::gtest GTest::gtest_main clutterseg_options)
  clutterseg_discover_tests(pcl_baseline_test TIMEOUT 600 LABELS pcl)
endif()
