# clutterseg-listen: prints the objects published by the daemon, writes label PNGs.
if(TARGET clutterseg::daemon_lib)
  add_executable(clutterseg_listen ${CMAKE_CURRENT_LIST_DIR}/clutterseg_listen.cc)
  set_target_properties(clutterseg_listen PROPERTIES OUTPUT_NAME clutterseg-listen)
  target_link_libraries(clutterseg_listen PRIVATE clutterseg::daemon_lib CLI11::CLI11
    clutterseg_options)
endif()
