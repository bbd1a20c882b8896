if(TARGET clutterseg::pipeline AND TARGET clutterseg::io AND TARGET clutterseg::config)
  add_executable(clutterseg-segment clutterseg_segment.cc)
  target_link_libraries(clutterseg-segment PRIVATE clutterseg::pipeline clutterseg::io
                        clutterseg::config CLI11::CLI11 nlohmann_json::nlohmann_json
                        clutterseg_options)
endif()
