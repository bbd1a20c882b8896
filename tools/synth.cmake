# clutterseg-synth: synthetic labelled tabletop scenes (organized PCD, optional PNGs, or an .oni
# recording when the ONI writer is built).
if(TARGET clutterseg::synth AND TARGET clutterseg::io)
  add_executable(clutterseg-synth ${CMAKE_CURRENT_LIST_DIR}/clutterseg_synth.cc)
  target_link_libraries(clutterseg-synth PRIVATE clutterseg::synth clutterseg::io CLI11::CLI11
                        clutterseg_options)
  if(TARGET clutterseg_oni)
    target_link_libraries(clutterseg-synth PRIVATE clutterseg_oni)
    target_compile_definitions(clutterseg-synth PRIVATE CLUTTERSEG_SYNTH_WITH_ONI=1)
  endif()
endif()
