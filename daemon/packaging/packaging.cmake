# SPDX-License-Identifier: MIT
# Packaging of the daemon: cmake --install rules (binaries, units, sysusers/tmpfiles entries,
# udev rule, configuration, documents, where Debian expects them with the prefix /usr) and CPack
# for a .deb whose maintainer scripts create the user and group and enable the socket.
#   cmake -S . -B build -DCMAKE_INSTALL_PREFIX=/usr
#   cmake --build build --target scanmeshd scanctl && (cd build && cpack -G DEB)
install(TARGETS scanmeshd scanctl RUNTIME DESTINATION bin COMPONENT daemon)
install(FILES ${PROJECT_SOURCE_DIR}/config/systemd/scanmesh.socket
        DESTINATION lib/systemd/system COMPONENT daemon)
install(FILES ${PROJECT_SOURCE_DIR}/config/systemd/scanmesh.sysusers
        DESTINATION lib/sysusers.d RENAME scanmesh.conf COMPONENT daemon)
install(FILES ${PROJECT_SOURCE_DIR}/config/systemd/scanmesh.tmpfiles
        DESTINATION lib/tmpfiles.d RENAME scanmesh.conf COMPONENT daemon)
install(FILES ${PROJECT_SOURCE_DIR}/config/systemd/60-scanmesh.rules
        DESTINATION lib/udev/rules.d COMPONENT daemon)
install(FILES ${CMAKE_CURRENT_SOURCE_DIR}/README.md ${CMAKE_CURRENT_SOURCE_DIR}/PROTOCOL.md
        ${PROJECT_SOURCE_DIR}/config/scanmesh-sim.toml
        DESTINATION share/doc/scanmesh COMPONENT daemon)
install(CODE "set(SCANMESH_DAEMON_SOURCE_DIR \"${PROJECT_SOURCE_DIR}\")\nset(SCANMESH_DAEMON_BINARY_DIR \"${CMAKE_CURRENT_BINARY_DIR}\")" COMPONENT daemon)
install(SCRIPT ${CMAKE_CURRENT_SOURCE_DIR}/packaging/install_daemon.cmake COMPONENT daemon)

set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME scanmesh)
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "3D scanner daemon: drives sensors and stages, meshes while scanning")
set(CPACK_PACKAGE_CONTACT "scanmesh maintainers <scanmesh@localhost>")
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_INSTALL_CMAKE_PROJECTS "${CMAKE_BINARY_DIR};${PROJECT_NAME};daemon;/")
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_SECTION science)
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
set(CPACK_DEBIAN_PACKAGE_DEPENDS "systemd, init-system-helpers, udev")
set(CPACK_DEBIAN_PACKAGE_CONTROL_EXTRA
    ${CMAKE_CURRENT_SOURCE_DIR}/packaging/postinst ${CMAKE_CURRENT_SOURCE_DIR}/packaging/prerm
    ${CMAKE_CURRENT_SOURCE_DIR}/packaging/postrm ${CMAKE_CURRENT_SOURCE_DIR}/packaging/conffiles)
set(CPACK_DEBIAN_PACKAGE_CONTROL_STRICT_PERMISSION TRUE)
include(CPack)
