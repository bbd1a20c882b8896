# clutterseg-eval: scores predicted label clouds against ground truth (METHOD.md section 7).
if(TARGET clutterseg::eval AND TARGET clutterseg::io)
  add_executable(clutterseg-eval ${CMAKE_CURRENT_LIST_DIR}/clutterseg_eval.cc)
  target_link_libraries(clutterseg-eval PRIVATE clutterseg::eval clutterseg::io CLI11::CLI11
                        clutterseg_options)
endif()
