# SPDX-License-Identifier: MIT
# Install-time part of the daemon's install rules (run by cmake --install and by CPack): the
# service unit and the configuration depend on the prefix chosen at install time. With the
# prefix /usr (Debian, the .deb) the configuration goes to /etc, otherwise to PREFIX/etc.
# Inputs: SCANMESH_DAEMON_SOURCE_DIR (the repository root), SCANMESH_DAEMON_BINARY_DIR.
set(prefix "${CMAKE_INSTALL_PREFIX}")
if(prefix STREQUAL "/usr")
  set(etc "/etc")
else()
  set(etc "${prefix}/etc")
endif()
set(SCANMESHD "${prefix}/bin/scanmeshd")
set(SCANMESH_CONFIG "${etc}/scanmesh/scanmesh.toml")
set(generated "${SCANMESH_DAEMON_BINARY_DIR}/scanmesh.service")
configure_file("${SCANMESH_DAEMON_SOURCE_DIR}/config/systemd/scanmesh.service.in" "${generated}" @ONLY)
file(INSTALL "${generated}" DESTINATION "${prefix}/lib/systemd/system")
# The configuration is the operator's (a conffile in the .deb): an existing one is kept.
if(EXISTS "$ENV{DESTDIR}${etc}/scanmesh/scanmesh.toml")
  message(STATUS "Keeping: $ENV{DESTDIR}${etc}/scanmesh/scanmesh.toml")
else()
  file(INSTALL "${SCANMESH_DAEMON_SOURCE_DIR}/config/scanmesh-sim.toml" DESTINATION "${etc}/scanmesh"
       RENAME scanmesh.toml)
endif()
