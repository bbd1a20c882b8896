# Generates the clutterseg LCM message bindings with lcm-gen at build time:
#   C++ headers   -> ${CLUTTERSEG_LCMTYPES_CPP_DIR}/clutterseg/*.hpp  (target clutterseg::lcmtypes)
#   Python        -> ${CLUTTERSEG_LCMTYPES_PYTHON_DIR}/clutterseg/*.py (pure struct, no lcm module)
#   Java (lcm-spy)-> ${CMAKE_CURRENT_BINARY_DIR}/clutterseg_lcmtypes.jar when javac and lcm.jar exist
# Debian's LCM 1.3.1 ships no CMake config and its lcm.pc needs glib, so LCM is found by hand
# and linked as plain -llcm.

find_program(CLUTTERSEG_LCM_GEN lcm-gen)
find_library(CLUTTERSEG_LCM_LIBRARY NAMES lcm)
find_path(CLUTTERSEG_LCM_INCLUDE_DIR lcm/lcm-cpp.hpp)
if(NOT CLUTTERSEG_LCM_GEN OR NOT CLUTTERSEG_LCM_LIBRARY OR NOT CLUTTERSEG_LCM_INCLUDE_DIR)
  message(FATAL_ERROR "CLUTTERSEG_WITH_LCM needs lcm-gen, liblcm and lcm/lcm-cpp.hpp "
                      "(apt-get install liblcm-dev liblcm-bin), or -DCLUTTERSEG_WITH_LCM=OFF")
endif()

# Every message type; the file name is the type name.
set(CLUTTERSEG_LCM_TYPES
  intrinsics_t
  plane_t
  object_t
  lost_track_t
  stage_times_t
  objects_t
  label_image_t
  depth_image_t
  status_t)

set(CLUTTERSEG_LCMTYPES_CPP_DIR "${CMAKE_CURRENT_BINARY_DIR}/cpp" CACHE INTERNAL "")
set(CLUTTERSEG_LCMTYPES_PYTHON_DIR "${CMAKE_CURRENT_BINARY_DIR}/python" CACHE INTERNAL "")
set(_lcm_java_dir "${CMAKE_CURRENT_BINARY_DIR}/java")

set(_lcm_sources "")
set(_lcm_cpp_outputs "")
set(_lcm_py_outputs "${CLUTTERSEG_LCMTYPES_PYTHON_DIR}/clutterseg/__init__.py")
set(_lcm_java_outputs "")
foreach(t IN LISTS CLUTTERSEG_LCM_TYPES)
  list(APPEND _lcm_sources "${CMAKE_CURRENT_SOURCE_DIR}/clutterseg/${t}.lcm")
  list(APPEND _lcm_cpp_outputs "${CLUTTERSEG_LCMTYPES_CPP_DIR}/clutterseg/${t}.hpp")
  list(APPEND _lcm_py_outputs "${CLUTTERSEG_LCMTYPES_PYTHON_DIR}/clutterseg/${t}.py")
  list(APPEND _lcm_java_outputs "${_lcm_java_dir}/clutterseg/${t}.java")
endforeach()

add_custom_command(
  OUTPUT ${_lcm_cpp_outputs}
  COMMAND ${CLUTTERSEG_LCM_GEN} --cpp --cpp-std c++11 --cpp-hpath "${CLUTTERSEG_LCMTYPES_CPP_DIR}"
          ${_lcm_sources}
  DEPENDS ${_lcm_sources}
  COMMENT "lcm-gen --cpp: clutterseg message types"
  VERBATIM)
# The Python package also holds our own modules: a udpm / log-file receiver (Debian has no
# python3-lcm) and the label image codec. Its __init__.py is ours (it also imports the
# compiled part, python/, when that is installed); lcm-gen keeps an existing __init__.py and
# appends the imports of the message types.
set(_lcm_py_extras "${CMAKE_CURRENT_SOURCE_DIR}/python/transport.py"
                   "${CMAKE_CURRENT_SOURCE_DIR}/python/label_image_codec.py")
add_custom_command(
  OUTPUT ${_lcm_py_outputs} "${CLUTTERSEG_LCMTYPES_PYTHON_DIR}/clutterseg/transport.py"
         "${CLUTTERSEG_LCMTYPES_PYTHON_DIR}/clutterseg/label_image_codec.py"
  COMMAND ${CMAKE_COMMAND} -E copy "${CMAKE_CURRENT_SOURCE_DIR}/python/__init__.py"
          "${CLUTTERSEG_LCMTYPES_PYTHON_DIR}/clutterseg/__init__.py"
  COMMAND ${CLUTTERSEG_LCM_GEN} --python --ppath "${CLUTTERSEG_LCMTYPES_PYTHON_DIR}" ${_lcm_sources}
  COMMAND ${CMAKE_COMMAND} -E copy ${_lcm_py_extras} "${CLUTTERSEG_LCMTYPES_PYTHON_DIR}/clutterseg/"
  DEPENDS ${_lcm_sources} ${_lcm_py_extras} "${CMAKE_CURRENT_SOURCE_DIR}/python/__init__.py"
  COMMENT "lcm-gen --python: clutterseg message types"
  VERBATIM)
add_custom_target(clutterseg_lcmtypes_gen ALL DEPENDS ${_lcm_cpp_outputs} ${_lcm_py_outputs}
                  "${CLUTTERSEG_LCMTYPES_PYTHON_DIR}/clutterseg/transport.py")

# Header-only interface target: generated headers (and the hand-written label image codec of
# cpp/) as a system include (they warn under -Wpedantic), plus liblcm and zlib.
find_package(ZLIB REQUIRED)
add_library(clutterseg_lcmtypes INTERFACE)
add_library(clutterseg::lcmtypes ALIAS clutterseg_lcmtypes)
set_target_properties(clutterseg_lcmtypes PROPERTIES EXPORT_NAME lcmtypes)
add_dependencies(clutterseg_lcmtypes clutterseg_lcmtypes_gen)
target_include_directories(clutterseg_lcmtypes SYSTEM INTERFACE
  "$<BUILD_INTERFACE:${CLUTTERSEG_LCMTYPES_CPP_DIR}>"
  "$<BUILD_INTERFACE:${CMAKE_CURRENT_SOURCE_DIR}/cpp>"
  "$<BUILD_INTERFACE:${CLUTTERSEG_LCM_INCLUDE_DIR}>"
  "$<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>")
target_link_libraries(clutterseg_lcmtypes INTERFACE
  "$<BUILD_INTERFACE:${CLUTTERSEG_LCM_LIBRARY}>" "$<INSTALL_INTERFACE:lcm>" ZLIB::ZLIB)

include(GNUInstallDirs)
install(DIRECTORY "${CLUTTERSEG_LCMTYPES_CPP_DIR}/clutterseg" "${CMAKE_CURRENT_SOURCE_DIR}/cpp/clutterseg"
        DESTINATION ${CMAKE_INSTALL_INCLUDEDIR} COMPONENT bindings FILES_MATCHING PATTERN "*.hpp")
install(FILES ${_lcm_sources}
        DESTINATION ${CMAKE_INSTALL_DATADIR}/clutterseg/lcmtypes/clutterseg COMPONENT bindings)
install(DIRECTORY "${CLUTTERSEG_LCMTYPES_PYTHON_DIR}/clutterseg"
        DESTINATION lib/python3/dist-packages COMPONENT bindings
        FILES_MATCHING PATTERN "*.py" PATTERN "__pycache__" EXCLUDE)

# Java classes for lcm-spy (java -cp /usr/share/java/lcm.jar:.../clutterseg_lcmtypes.jar
# lcm.spy.Spy), built only when a JDK and lcm.jar are present.
find_program(CLUTTERSEG_JAVAC javac)
find_program(CLUTTERSEG_JAR jar)
find_file(CLUTTERSEG_LCM_JAR lcm.jar PATHS /usr/share/java NO_DEFAULT_PATH)
if(CLUTTERSEG_JAVAC AND CLUTTERSEG_JAR AND CLUTTERSEG_LCM_JAR)
  set(_lcm_jar_out "${CMAKE_CURRENT_BINARY_DIR}/clutterseg_lcmtypes.jar")
  set(_lcm_class_dir "${CMAKE_CURRENT_BINARY_DIR}/java_classes")
  add_custom_command(
    OUTPUT ${_lcm_jar_out}
    COMMAND ${CMAKE_COMMAND} -E rm -rf "${_lcm_java_dir}" "${_lcm_class_dir}"
    COMMAND ${CLUTTERSEG_LCM_GEN} --java --jpath "${_lcm_java_dir}" ${_lcm_sources}
    COMMAND ${CMAKE_COMMAND} -E make_directory "${_lcm_class_dir}"
    COMMAND ${CLUTTERSEG_JAVAC} -nowarn -cp "${CLUTTERSEG_LCM_JAR}" -d "${_lcm_class_dir}"
            ${_lcm_java_outputs} "${CMAKE_CURRENT_SOURCE_DIR}/java/clutterseg/LabelImageCodec.java"
    COMMAND ${CLUTTERSEG_JAR} cf "${_lcm_jar_out}" -C "${_lcm_class_dir}" .
    DEPENDS ${_lcm_sources} "${CMAKE_CURRENT_SOURCE_DIR}/java/clutterseg/LabelImageCodec.java"
    COMMENT "lcm-gen --java + javac: clutterseg_lcmtypes.jar for lcm-spy"
    VERBATIM)
  add_custom_target(clutterseg_lcmtypes_jar ALL DEPENDS ${_lcm_jar_out})
  set(CLUTTERSEG_LCMTYPES_JAR "${_lcm_jar_out}" CACHE INTERNAL "")
  install(FILES "${_lcm_jar_out}" DESTINATION ${CMAKE_INSTALL_DATADIR}/java COMPONENT bindings)
else()
  message(STATUS "clutterseg: javac or /usr/share/java/lcm.jar missing; no lcm-spy jar")
endif()
