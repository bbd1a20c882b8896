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

# clutterseg_public_headers(<target> <subdir>)   e.g. (clutterseg_core core),
# (clutterseg_driver_oni drivers/oni). Call from the module's own CMakeLists.txt.
function(clutterseg_public_headers target subdir)
  set(root "${PROJECT_BINARY_DIR}/include/${target}")
  set(link "${root}/clutterseg/${subdir}")
  get_filename_component(parent "${link}" DIRECTORY)
  file(MAKE_DIRECTORY "${parent}")
  if(NOT IS_SYMLINK "${link}")
    file(CREATE_LINK "${CMAKE_CURRENT_SOURCE_DIR}" "${link}" SYMBOLIC)
  endif()
  get_target_property(type ${target} TYPE)
  if(type STREQUAL "INTERFACE_LIBRARY")
    target_include_directories(${target} INTERFACE "$<BUILD_INTERFACE:${root}>"
                               "$<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>")
  else()
    target_include_directories(${target} PUBLIC "$<BUILD_INTERFACE:${root}>"
                               "$<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>")
  endif()
  set_property(TARGET ${target} PROPERTY CLUTTERSEG_HEADER_SUBDIR "${subdir}")
endfunction()
