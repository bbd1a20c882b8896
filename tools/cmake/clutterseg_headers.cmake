# Public headers of a module target, spelled with the project prefix in the build tree as they
# are once installed: the headers of src/<m>/ are included as "clutterseg/<m>/x.h", those of
# drivers/<d>/ as "clutterseg/drivers/<d>/x.h".
#
# Each target gets an include root of its own, ${PROJECT_BINARY_DIR}/include/<target>, that
# holds a single link clutterseg/<subdir> -> the module's source directory, and exposes it
# PUBLIC. A target therefore sees the headers of the modules it links (its own layer and the
# layers below, through their PUBLIC links) and nothing else: an include that reaches up a
# layer does not compile. tools/check_layering.py checks the same rule on the sources.
include_guard(GLOBAL)
include(GNUInstallDirs)

# clutterseg_public_headers(<target> <subdir> [NO_INSTALL])   e.g. (clutterseg_core core),
# (clutterseg_oni drivers/oni). Call from the module's own CMakeLists.txt. Unless
# NO_INSTALL, the library and its public headers (not internal/) are installed (component
# dev) and the target joins the exported package `clutterseg::` as clutterseg::<name>, its
# name without the clutterseg_ prefix.
function(clutterseg_public_headers target subdir)
  cmake_parse_arguments(ARG "NO_INSTALL" "" "" ${ARGN})
  set(root "${PROJECT_BINARY_DIR}/include/${target}")
  set(link "${root}/clutterseg/${subdir}")
  get_filename_component(parent "${link}" DIRECTORY)
  file(MAKE_DIRECTORY "${parent}")
  if(NOT IS_SYMLINK "${link}")
    file(CREATE_LINK "${CMAKE_CURRENT_SOURCE_DIR}" "${link}" SYMBOLIC)
  endif()
  get_target_property(type ${target} TYPE)
  if(type STREQUAL "INTERFACE_LIBRARY")
    set(scope INTERFACE)
  else()
    set(scope PUBLIC)
  endif()
  target_include_directories(${target} ${scope} "$<BUILD_INTERFACE:${root}>"
                             "$<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>")
  if(ARG_NO_INSTALL)
    return()
  endif()
  string(REGEX REPLACE "^clutterseg_" "" export_name "${target}")
  set_target_properties(${target} PROPERTIES EXPORT_NAME ${export_name})
  install(TARGETS ${target} EXPORT clutterseg-targets
          ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT dev)
  install(DIRECTORY "${CMAKE_CURRENT_SOURCE_DIR}/"
          DESTINATION "${CMAKE_INSTALL_INCLUDEDIR}/clutterseg/${subdir}" COMPONENT dev
          FILES_MATCHING PATTERN "*.h"
          PATTERN "internal" EXCLUDE)
  set_property(GLOBAL APPEND PROPERTY CLUTTERSEG_INSTALLED_LIBRARIES ${export_name})
endfunction()
