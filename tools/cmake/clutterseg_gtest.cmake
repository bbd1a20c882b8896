# clutterseg_discover_tests(TARGET TIMEOUT SECONDS [LABELS label...])
# Registers the gtest tests of TARGET with ctest. Tests that read the real data sets have
# "RealData" in their suite name (CLUTTERSEG_REQUIRE_DATA in tests/testing/test_data.h checks
# it) and get the label `realdata` besides LABELS; the rest run on data the project makes
# itself. See docs/testing.md.
include(GoogleTest)
function(clutterseg_discover_tests target)
  cmake_parse_arguments(ARG "" "TIMEOUT" "LABELS" ${ARGN})
  gtest_discover_tests(${target} DISCOVERY_TIMEOUT 60 TEST_FILTER "-*RealData*"
    TEST_LIST ${target}_TESTS PROPERTIES TIMEOUT ${ARG_TIMEOUT} LABELS "${ARG_LABELS}")
  gtest_discover_tests(${target} DISCOVERY_TIMEOUT 60 TEST_FILTER "*RealData*"
    TEST_LIST ${target}_REALDATA_TESTS PROPERTIES TIMEOUT ${ARG_TIMEOUT})
  # gtest_discover_tests passes a property's list split into words, so the labels of the
  # second group are set by an include file that ctest reads after the discovered tests.
  set(labels ${ARG_LABELS} realdata)
  set(labels_file "${CMAKE_CURRENT_BINARY_DIR}/${target}_realdata_labels.cmake")
  file(WRITE "${labels_file}" "if(${target}_REALDATA_TESTS)\n"
    "  set_tests_properties(\${${target}_REALDATA_TESTS} PROPERTIES LABELS \"${labels}\")\n"
    "endif()\n")
  set_property(DIRECTORY APPEND PROPERTY TEST_INCLUDE_FILES "${labels_file}")
endfunction()
