# The Debian package of the robot (CPack, DEB generator): docs/packaging.md.
#   make package                    both packages (host and aarch64), out/package/
#   cpack --config <build>/CPackConfig.cmake   the package of one build dir
# One package, "coslam-robot", built from whatever build dir it is run in:
# amd64 from the host build, arm64 from the cross build (toolchain-aarch64).
# Contents (install component "robot"; nothing else of the project is packaged):
#   /usr/bin/coslam-robot
#   /etc/coslam/robot.ini                     default configuration (conffile)
#   /lib/systemd/system/coslam-robot.service  the service (not enabled on install)
#   /lib/udev/rules.d/60-coslam-gpio.rules    /dev/gpiochip* to group gpio
#   /usr/share/coslam/vision/                 colour table and range model (hook below)
#   /usr/share/doc/coslam-robot/              README.md (docs/robot.md), packaging.md
# Maintainer scripts: firmware/port/linux/dist/debian/ (service user, groups,
# state directory; purge removes the snapshots).
if(NOT TARGET coslam-robot)
  message(STATUS "package: no coslam-robot target in this build, no package")
  return()
endif()
include(GNUInstallDirs)
set(_dist ${PROJECT_SOURCE_DIR}/firmware/port/linux/dist)

install(TARGETS coslam-robot RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT robot)
# /etc and /lib are absolute: outside CMAKE_INSTALL_PREFIX (/usr in the package)
install(FILES ${PROJECT_SOURCE_DIR}/firmware/port/linux/robot.ini DESTINATION /etc/coslam COMPONENT robot)
install(FILES ${_dist}/coslam-robot.service DESTINATION /lib/systemd/system COMPONENT robot)
install(FILES ${_dist}/60-coslam-gpio.rules DESTINATION /lib/udev/rules.d COMPONENT robot)
install(FILES ${PROJECT_SOURCE_DIR}/docs/robot.md DESTINATION ${CMAKE_INSTALL_DATAROOTDIR}/doc/coslam-robot
        RENAME README.md COMPONENT robot)
install(FILES ${PROJECT_SOURCE_DIR}/docs/packaging.md DESTINATION ${CMAKE_INSTALL_DATAROOTDIR}/doc/coslam-robot
        COMPONENT robot)

# --- COLOUR TABLE HOOK ------------------------------------------------------
# The colour table (and range model) of the marker detector are made by the
# host/vision tools and kept in firmware/vision/data/ (firmware/vision's
# COSLAM_VISION_DATA_DIR). Until the vision work commits one, that folder is
# empty and the package ships none; every file that appears there is
# installed to /usr/share/coslam/vision/ with no change here (reconfigure).
file(GLOB COSLAM_PKG_VISION_DATA CONFIGURE_DEPENDS ${PROJECT_SOURCE_DIR}/firmware/vision/data/*)
if(COSLAM_PKG_VISION_DATA)
  install(FILES ${COSLAM_PKG_VISION_DATA} DESTINATION ${CMAKE_INSTALL_DATADIR}/coslam/vision COMPONENT robot)
else()
  message(STATUS "package: no colour table in firmware/vision/data yet: the package ships none")
endif()
# ---------------------------------------------------------------------------

# conffiles: dpkg keeps local edits of these across upgrades and asks
set(_ctl ${CMAKE_BINARY_DIR}/cpack-deb)
file(MAKE_DIRECTORY ${_ctl})
file(WRITE ${_ctl}/conffiles "/etc/coslam/robot.ini\n")

# Debian architecture of the target, not of the build machine
if(CMAKE_SYSTEM_PROCESSOR MATCHES "^(aarch64|arm64)$")
  set(_deb_arch arm64)
elseif(CMAKE_SYSTEM_PROCESSOR MATCHES "^(x86_64|AMD64|amd64)$")
  set(_deb_arch amd64)
else()
  execute_process(COMMAND dpkg --print-architecture OUTPUT_VARIABLE _deb_arch OUTPUT_STRIP_TRAILING_WHITESPACE)
endif()

set(COSLAM_PKG_MAINTAINER "coslam maintainers <coslam@localhost>" CACHE STRING "Maintainer field of the Debian package")
set(CPACK_GENERATOR DEB)
set(CPACK_SOURCE_GENERATOR "")
set(CPACK_PACKAGE_NAME coslam-robot)
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_CONTACT "${COSLAM_PKG_MAINTAINER}")
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_STRIP_FILES ON)
# only the robot component (other folders may add install rules of their own)
set(CPACK_COMPONENTS_ALL robot)
set(CPACK_DEB_COMPONENT_INSTALL ON)
set(CPACK_COMPONENTS_GROUPING ALL_COMPONENTS_IN_ONE)
set(CPACK_DEBIAN_PACKAGE_NAME coslam-robot)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_RELEASE 1)
set(CPACK_DEBIAN_PACKAGE_ARCHITECTURE ${_deb_arch})
set(CPACK_DEBIAN_PACKAGE_SECTION misc)
set(CPACK_DEBIAN_PACKAGE_PRIORITY optional)
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "cooperative SLAM robot node (coslam)")
# (CPack puts the summary first and formats the lines)
string(CONCAT CPACK_DEBIAN_PACKAGE_DESCRIPTION
  "coslam-robot runs the coslam robot application on Linux: Fast-SLAM or\n"
  "EKF-SLAM on wheel odometry and camera sightings of markers, a Hokuyo URG\n"
  "laser (SCIP 2.0) for obstacles, CiA 402 wheel drives over SocketCAN, GPIO\n"
  "bumper, e-stop and LEDs through libgpiod, and map merging with the other\n"
  "robots of its fleet over Cyclone DDS, authenticated with a fleet key.\n"
  "Installs a systemd service, not enabled on install.")
# Depends: the shared libraries the binary links (dpkg-shlibdeps, which reads
# the arm64 libraries' shlibs/symbols from the multiarch packages in a cross
# build), plus adduser for the postinst.
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
set(CPACK_DEBIAN_PACKAGE_DEPENDS "adduser")
set(CPACK_DEBIAN_PACKAGE_CONTROL_EXTRA ${_ctl}/conffiles ${_dist}/debian/postinst ${_dist}/debian/prerm
    ${_dist}/debian/postrm)
set(CPACK_DEBIAN_PACKAGE_CONTROL_STRICT_PERMISSION ON)
# cpack must not build the whole project first (its "preinstall" step
# depends on "all" otherwise): `make package` builds coslam-robot itself.
set(CMAKE_SKIP_INSTALL_ALL_DEPENDENCY ON)
include(CPack)
