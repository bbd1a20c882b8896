# clutterseg-synth: synthetic labelled tabletop scenes (organized PCD, optional PNGs).
if(TARGET clutterseg::synth AND TARGET clutterseg::io)
  add_executable(clutterseg-synth ${CMAKE_CURRENT_LIST_DIR}/clutterseg_synth.cc)
  target_link_libraries(clutterseg-synth PRIVATE clutterseg::synth clutterseg::io CLI11::CLI11
                        clutterseg_options)
endif()
