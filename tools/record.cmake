# clutterseg-record: records a live OpenNI2 camera to .oni, or builds an .oni from PCD files.
if(TARGET clutterseg_driver_openni2 AND TARGET clutterseg_driver_replay AND TARGET clutterseg_oni)
  add_executable(clutterseg-record ${CMAKE_CURRENT_LIST_DIR}/clutterseg_record.cc)
  target_link_libraries(clutterseg-record PRIVATE clutterseg::driver_openni2
                        clutterseg::driver_replay clutterseg::oni clutterseg_openni2_headers
                        CLI11::CLI11 clutterseg_options)
endif()

if(TARGET clutterseg-record AND CLUTTERSEG_BUILD_TESTS)
  # Without a camera the live mode must fail cleanly (exit code 3: the source cannot be opened).
  add_test(NAME clutterseg_record.no_device
           COMMAND sh -c "out=$(\"$0\" \"$1\" --frames 1 2>&1); rc=$?; echo \"$out\"; test $rc -eq 3 && echo \"$out\" | grep -q \"no OpenNI2 device is connected\""
                   $<TARGET_FILE:clutterseg-record> ${CMAKE_CURRENT_BINARY_DIR}/no_device.oni)
  set_tests_properties(clutterseg_record.no_device PROPERTIES
    FAIL_REGULAR_EXPRESSION "Sanitizer|runtime error" TIMEOUT 60 LABELS "drivers")
  if(TARGET clutterseg-synth)
    # PCD frames with colour written by clutterseg-synth, recorded into an .oni.
    add_test(NAME clutterseg_record.synth_pcds
             COMMAND clutterseg-synth --out ${CMAKE_CURRENT_BINARY_DIR}/record_pcds --count 3
                     --seed 4)
    set_tests_properties(clutterseg_record.synth_pcds PROPERTIES
      FIXTURES_SETUP clutterseg_record_pcds TIMEOUT 120 LABELS "drivers")
    add_test(NAME clutterseg_record.from_pcd
             COMMAND clutterseg-record ${CMAKE_CURRENT_BINARY_DIR}/from_pcd.oni
                     --from-pcd ${CMAKE_CURRENT_BINARY_DIR}/record_pcds --frames 3)
    set_tests_properties(clutterseg_record.from_pcd PROPERTIES
      PASS_REGULAR_EXPRESSION "wrote 3 frames \\(depth\\+color\\)"
      FIXTURES_REQUIRED clutterseg_record_pcds
      FAIL_REGULAR_EXPRESSION "Sanitizer|runtime error" TIMEOUT 60 LABELS "drivers")
  endif()
endif()
