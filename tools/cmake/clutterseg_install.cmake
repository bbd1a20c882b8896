# Installation and packaging: `cmake --install` and CPack's Debian packages.
#
#   component daemon   -> clutterseg           the daemon and tools, config, systemd unit, udev
#                                               rule, OpenNI2 recordings-only driver links, docs
#   component dev      -> libclutterseg-dev    headers <clutterseg/...>, static libraries, the
#                                               CMake package clutterseg:: and clutterseg.pc
#   component bindings -> clutterseg-lcmtypes  the .lcm files and their C++, Python and Java
#                                               bindings (with the label image codec),
#                                               clutterseg-spy
#   component python   -> python3-clutterseg   the compiled part of the Python package
#                                               (clutterseg._core: Segmenter, read_pcd, ...),
#                                               beside the bindings' pure-Python modules
#
# Layout under the prefix (GNUInstallDirs; the presets configure CMAKE_INSTALL_PREFIX=/usr,
# Debian's layout; stage elsewhere with DESTDIR=/some/root cmake --install build/release):
#   bin/                                   clutterseg, clutterseg-segment, -eval, -synth, ...
#   include/clutterseg/<module>/           library headers; include/clutterseg/*.hpp bindings
#   lib/<multiarch>/                       libclutterseg_<module>.a, cmake/clutterseg/,
#                                          pkgconfig/clutterseg.pc,
#                                          clutterseg/openni2-recordings/
#   lib/python3/dist-packages/clutterseg/  Python bindings, and _core.cpython-*.so
#   share/java/clutterseg_lcmtypes.jar     Java bindings (lcm-spy)
#   share/clutterseg/lcmtypes/clutterseg/  the .lcm files
#   share/clutterseg/config/               paper.yaml, previous-defaults.yaml (and the shipped defaults)
#   /etc/clutterseg/clutterseg.yaml        the daemon's configuration (the prefix's sysconfdir)
#   lib/systemd/system/clutterseg.service, clutterseg@.service, lib/udev/rules.d/50-clutterseg.rules
include_guard(GLOBAL)
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

set(CLUTTERSEG_INSTALL_CMAKEDIR "${CMAKE_INSTALL_LIBDIR}/cmake/clutterseg")
set(CLUTTERSEG_INSTALL_LCMTYPES_DIR "${CMAKE_INSTALL_DATADIR}/clutterseg/lcmtypes")
set(CLUTTERSEG_INSTALL_PYTHONDIR "lib/python3/dist-packages")
set(CLUTTERSEG_INSTALL_JAVADIR "${CMAKE_INSTALL_DATADIR}/java")

# ---- binaries -----------------------------------------------------------------------------
foreach(t clutterseg clutterseg-segment clutterseg-eval clutterseg-synth clutterseg-record
          clutterseg_listen clutterseg_regress clutterseg-bench)
  if(TARGET ${t})
    install(TARGETS ${t} RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT daemon)
  endif()
endforeach()

# The Python module (src/python/), in the package directory of the Python LCM bindings.
if(TARGET clutterseg_python_core)
  install(TARGETS clutterseg_python_core
          LIBRARY DESTINATION ${CLUTTERSEG_INSTALL_PYTHONDIR}/clutterseg COMPONENT python)
  if(NOT TARGET clutterseg_lcmtypes_gen)  # without LCM the package is the module alone
    install(FILES "${CLUTTERSEG_PYTHON_PACKAGE_DIR}/__init__.py"
            DESTINATION ${CLUTTERSEG_INSTALL_PYTHONDIR}/clutterseg COMPONENT python)
  endif()
endif()

install(PROGRAMS "${PROJECT_SOURCE_DIR}/tools/clutterseg-spy.sh" RENAME clutterseg-spy
        DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT bindings)

# ---- the library package ------------------------------------------------------------------
get_property(_libs GLOBAL PROPERTY CLUTTERSEG_INSTALLED_LIBRARIES)
add_library(clutterseg_all INTERFACE)
set_target_properties(clutterseg_all PROPERTIES EXPORT_NAME clutterseg)
set(_pc_libs "")
# Link order for static archives: dependents before what they use.
foreach(m config pipeline optimize graph supervoxel geometry driver_openni2 driver_replay oni
          synth eval io core)
  if(m IN_LIST _libs)
    target_link_libraries(clutterseg_all INTERFACE clutterseg::${m})
    string(APPEND _pc_libs " -lclutterseg_${m}")
  endif()
endforeach()
install(TARGETS clutterseg_all EXPORT clutterseg-targets COMPONENT dev)
if(TARGET clutterseg_lcmtypes)
  install(TARGETS clutterseg_lcmtypes EXPORT clutterseg-targets COMPONENT bindings)
endif()
install(EXPORT clutterseg-targets NAMESPACE clutterseg:: FILE clutterseg-targets.cmake
        DESTINATION ${CLUTTERSEG_INSTALL_CMAKEDIR} COMPONENT dev)
configure_package_config_file(
  "${CMAKE_CURRENT_LIST_DIR}/clutterseg-config.cmake.in"
  "${PROJECT_BINARY_DIR}/clutterseg-config.cmake"
  INSTALL_DESTINATION ${CLUTTERSEG_INSTALL_CMAKEDIR}
  PATH_VARS CLUTTERSEG_INSTALL_LCMTYPES_DIR)
write_basic_package_version_file("${PROJECT_BINARY_DIR}/clutterseg-config-version.cmake"
                                 COMPATIBILITY SameMinorVersion)
install(FILES "${PROJECT_BINARY_DIR}/clutterseg-config.cmake"
              "${PROJECT_BINARY_DIR}/clutterseg-config-version.cmake"
        DESTINATION ${CLUTTERSEG_INSTALL_CMAKEDIR} COMPONENT dev)
set(CLUTTERSEG_PC_LIBS "${_pc_libs}")
configure_file("${CMAKE_CURRENT_LIST_DIR}/clutterseg.pc.in" "${PROJECT_BINARY_DIR}/clutterseg.pc"
               @ONLY)
install(FILES "${PROJECT_BINARY_DIR}/clutterseg.pc"
        DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig COMPONENT dev)

# ---- configuration, service, udev, docs ---------------------------------------------------
# The daemon's configuration: /etc/clutterseg with the /usr prefix (GNUInstallDirs' full
# sysconfdir, so also with DESTDIR staging and in the package).
install(FILES "${PROJECT_SOURCE_DIR}/config/clutterseg.yaml"
        DESTINATION ${CMAKE_INSTALL_FULL_SYSCONFDIR}/clutterseg COMPONENT daemon)
install(FILES "${PROJECT_SOURCE_DIR}/config/clutterseg.yaml" "${PROJECT_SOURCE_DIR}/config/paper.yaml"
              "${PROJECT_SOURCE_DIR}/config/previous-defaults.yaml"
        DESTINATION ${CMAKE_INSTALL_DATADIR}/clutterseg/config COMPONENT daemon)
# One camera: clutterseg.service reads clutterseg.yaml.
set(CLUTTERSEG_UNIT_DESCRIPTION "clutterseg RGB-D tabletop segmentation daemon (LCM publisher)")
set(CLUTTERSEG_UNIT_ARGS "--config ${CMAKE_INSTALL_FULL_SYSCONFDIR}/clutterseg/clutterseg.yaml")
set(CLUTTERSEG_UNIT_REALTIME "RestrictRealtime=yes")
string(JOIN "\n" CLUTTERSEG_UNIT_USAGE
       "# This is clutterseg.service. The configuration is"
       "# ${CMAKE_INSTALL_FULL_SYSCONFDIR}/clutterseg/clutterseg.yaml. Enable with"
       "# `systemctl enable --now clutterseg`; after editing the file, `systemctl reload clutterseg`"
       "# re-reads the segmentation parameters.")
configure_file("${PROJECT_SOURCE_DIR}/config/clutterseg.service.in"
               "${PROJECT_BINARY_DIR}/clutterseg.service" @ONLY)
# Several cameras: clutterseg@NAME.service reads NAME.yaml and publishes camera NAME unless
# the file names another camera_name. The --default values are the settings measured for
# three cameras on a 2-core host (docs/daemon.md); NAME.yaml overrides any of them.
set(CLUTTERSEG_UNIT_DESCRIPTION "clutterseg segmentation daemon of camera %i (LCM publisher)")
set(CLUTTERSEG_UNIT_ARGS "--config ${CMAKE_INSTALL_FULL_SYSCONFDIR}/clutterseg/%i.yaml --default camera_name=%i --default processing.threads=1 --default processing.realtime_priority=10 --default camera.decimation=2")
# processing.realtime_priority 10: the lanes at SCHED_FIFO 10, the capture path at 11.
# camera.decimation 2: each camera processed at 320x240, so that three cameras keep their
# latency on two cores also when the host runs slower (docs/daemon.md, docs/results.md).
string(JOIN "\n" CLUTTERSEG_UNIT_REALTIME
       "# Real-time scheduling (processing.realtime_priority, default 10 here): the lanes at"
       "# SCHED_FIFO 10, the capture path and publisher at 11. The kernel keeps 5 % of each"
       "# second for the normal class (kernel.sched_rt_runtime_us). Set"
       "# processing.realtime_priority: 0 in NAME.yaml where other real-time work shares the host."
       "LimitRTPRIO=11"
       "RestrictRealtime=no")
string(JOIN "\n" CLUTTERSEG_UNIT_USAGE
       "# This is the template clutterseg@.service: instance NAME reads"
       "# ${CMAKE_INSTALL_FULL_SYSCONFDIR}/clutterseg/NAME.yaml (give each its camera.serial)."
       "# Enable with `systemctl enable --now clutterseg@left clutterseg@right`; after editing a"
       "# file, `systemctl reload clutterseg@left` re-reads its segmentation parameters."
       "# The --default values below (one thread, frames at 320x240, SCHED_FIFO 10) are sized for"
       "# three cameras on two cores; NAME.yaml overrides them (camera.decimation: 1 gives full"
       "# resolution back where the host has a core per camera).")
configure_file("${PROJECT_SOURCE_DIR}/config/clutterseg.service.in"
               "${PROJECT_BINARY_DIR}/clutterseg@.service" @ONLY)
install(FILES "${PROJECT_BINARY_DIR}/clutterseg.service" "${PROJECT_BINARY_DIR}/clutterseg@.service"
        DESTINATION lib/systemd/system COMPONENT daemon)
install(FILES "${PROJECT_SOURCE_DIR}/config/50-clutterseg.rules"
        DESTINATION lib/udev/rules.d COMPONENT daemon)
install(DIRECTORY "${PROJECT_SOURCE_DIR}/docs/"
        DESTINATION ${CMAKE_INSTALL_DOCDIR} COMPONENT daemon)
install(FILES "${PROJECT_SOURCE_DIR}/README.md" DESTINATION ${CMAKE_INSTALL_DOCDIR}
        COMPONENT daemon)

# ---- Debian packages (cpack -G DEB in the build directory) ---------------------------------
set(CPACK_PACKAGE_NAME clutterseg)
set(CPACK_PACKAGE_VENDOR "clutterseg")
set(CPACK_PACKAGE_VERSION "${PROJECT_VERSION}")
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY
    "Training-free segmentation of cluttered RGB-D tabletops, published over LCM")
set(CPACK_PACKAGE_CONTACT "clutterseg maintainers <maintainers@clutterseg.invalid>")
set(CPACK_GENERATOR DEB)
set(CPACK_DEB_COMPONENT_INSTALL ON)
set(CPACK_COMPONENTS_ALL daemon dev bindings)
if(TARGET clutterseg_python_core)
  list(APPEND CPACK_COMPONENTS_ALL python)
endif()
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_SECTION science)
set(CPACK_DEBIAN_PACKAGE_HOMEPAGE "https://clutterseg.invalid")
set(CPACK_DEBIAN_DAEMON_PACKAGE_NAME clutterseg)
set(CPACK_DEBIAN_DAEMON_PACKAGE_SHLIBDEPS ON)
# libOpenNI2 is loaded at run time (dlopen), so dpkg-shlibdeps cannot see it.
set(CPACK_DEBIAN_DAEMON_PACKAGE_DEPENDS "libopenni2-0")
set(CPACK_DEBIAN_DAEMON_PACKAGE_RECOMMENDS "clutterseg-lcmtypes (= ${PROJECT_VERSION})")
set(CPACK_DEBIAN_DAEMON_DESCRIPTION
    "clutterseg segmentation daemon and tools\n Reads an Asus Xtion / PrimeSense camera through OpenNI2 (or replays .oni\n recordings, PCD and depth PNG directories), segments every frame into objects\n and support planes and publishes them over LCM. Ships the systemd unit, the\n udev rule for the cameras and the documentation.")
set(CPACK_DEBIAN_DAEMON_PACKAGE_CONTROL_EXTRA "${PROJECT_SOURCE_DIR}/tools/packaging/conffiles"
    "${PROJECT_SOURCE_DIR}/tools/packaging/postinst"
    "${PROJECT_SOURCE_DIR}/tools/packaging/postrm")
set(CPACK_DEBIAN_DEV_PACKAGE_NAME libclutterseg-dev)
set(CPACK_DEBIAN_DEV_PACKAGE_DEPENDS
    "clutterseg-lcmtypes (= ${PROJECT_VERSION}), libeigen3-dev, libpng-dev, libdeflate-dev, libyaml-cpp-dev, liblcm-dev")
set(CPACK_DEBIAN_DEV_PACKAGE_SECTION libdevel)
set(CPACK_DEBIAN_DEV_DESCRIPTION
    "clutterseg segmentation library (development files)\n Headers <clutterseg/...>, static libraries, the CMake package\n (find_package(clutterseg), targets clutterseg::...) and clutterseg.pc.")
set(CPACK_DEBIAN_BINDINGS_PACKAGE_NAME clutterseg-lcmtypes)
set(CPACK_DEBIAN_BINDINGS_PACKAGE_ARCHITECTURE all)
set(CPACK_DEBIAN_BINDINGS_PACKAGE_DEPENDS "python3")
set(CPACK_DEBIAN_BINDINGS_PACKAGE_RECOMMENDS "liblcm-java, libjchart2d-java, default-jre, unzip")
set(CPACK_DEBIAN_BINDINGS_PACKAGE_SUGGESTS "liblcm-dev")
set(CPACK_DEBIAN_BINDINGS_DESCRIPTION
    "clutterseg LCM message types and bindings\n The .lcm files of the clutterseg messages and their generated bindings: C++\n headers, the Python package clutterseg (with a pure-Python LCM subscriber and the\n label image codec, no lcm module needed) and the Java jar for lcm-spy\n (clutterseg-spy).")
# Debian's name for a Python 3 module is python3-<module>; it is built for one Python version
# (the extension's ABI tag), so it depends on that version as dh_python3 would write it.
if(TARGET clutterseg_python_core)
  set(CPACK_DEBIAN_PYTHON_PACKAGE_NAME python3-clutterseg)
  set(CPACK_DEBIAN_PYTHON_PACKAGE_SECTION python)
  set(CPACK_DEBIAN_PYTHON_PACKAGE_SHLIBDEPS ON)
  math(EXPR _py_next_minor "${Python3_VERSION_MINOR} + 1")
  set(CPACK_DEBIAN_PYTHON_PACKAGE_DEPENDS
      "python3 (>= ${Python3_VERSION_MAJOR}.${Python3_VERSION_MINOR}), python3 (<< ${Python3_VERSION_MAJOR}.${_py_next_minor}), python3-numpy")
  if(TARGET clutterseg_lcmtypes_gen)  # the package's __init__.py and pure-Python part
    string(PREPEND CPACK_DEBIAN_PYTHON_PACKAGE_DEPENDS "clutterseg-lcmtypes (= ${PROJECT_VERSION}), ")
  endif()
  set(CPACK_DEBIAN_PYTHON_PACKAGE_SUGGESTS "python3-matplotlib")
  set(CPACK_DEBIAN_PYTHON_DESCRIPTION
      "clutterseg segmentation for Python\n The compiled module clutterseg._core of the Python package clutterseg:\n clutterseg.Segmenter segments numpy point clouds and depth images into\n objects and support planes (the same labels as clutterseg-segment);\n read_pcd, write_pcd and evaluate (the metrics of clutterseg-eval).")
endif()
include(CPack)
