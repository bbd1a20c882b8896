# clutterseg-regress: compares two LCM logs of daemon runs frame by frame.
if(TARGET clutterseg::daemon_lib)
  add_executable(clutterseg_regress ${CMAKE_CURRENT_LIST_DIR}/clutterseg_regress.cc)
  set_target_properties(clutterseg_regress PROPERTIES OUTPUT_NAME clutterseg-regress)
  target_link_libraries(clutterseg_regress PRIVATE clutterseg::daemon_lib CLI11::CLI11
    clutterseg_options)
endif()
