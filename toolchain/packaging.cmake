# Install rules and the Debian package of the firmware (CPack DEB): `cpack -G DEB` in a (cross) build dir.
# The package (component firmware) carries the board binary facetscan-fw only: no facetscan-fw-hil, no hw-sim
# scenes. Those go with the host program (component host, `cmake --install`): `facetscan demo` runs the
# facetscan-fw-hil next to it on the shipped scenes.
include(GNUInstallDirs)
install(TARGETS facetscan-fw RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT firmware)
install(FILES ${PROJECT_SOURCE_DIR}/toolchain/deploy/facetscan-fw.service
        DESTINATION lib/systemd/system COMPONENT firmware)
# The example board config lives outside /usr/share/doc (which minimal images may drop): postinst copies it to
# /etc/facetscan/board.json on first install.
install(FILES ${PROJECT_SOURCE_DIR}/toolchain/deploy/board.example.json
        DESTINATION ${CMAKE_INSTALL_DATAROOTDIR}/facetscan COMPONENT firmware)
install(FILES ${PROJECT_SOURCE_DIR}/README.md DESTINATION ${CMAKE_INSTALL_DATAROOTDIR}/doc/facetscan-fw
        COMPONENT firmware)
if(TARGET facetscan)
  install(TARGETS facetscan facetscan-fw-hil RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT host)
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/hw-sim/scenes/ DESTINATION ${CMAKE_INSTALL_DATAROOTDIR}/facetscan/scenes
          COMPONENT host OPTIONAL)
  # The fleet's NATS configs, certificate script and units (docs/fleet.md): `facetscan demo --fleet` starts a
  # nats-server from them.
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/toolchain/deploy/nats/ DESTINATION ${CMAKE_INSTALL_DATAROOTDIR}/facetscan/nats
          COMPONENT host USE_SOURCE_PERMISSIONS)
endif()

set(CPACK_PACKAGE_NAME facetscan)
set(CPACK_PACKAGE_VENDOR "Facetscan")
set(CPACK_PACKAGE_CONTACT "Facetscan developers <dev@facetscan.invalid>")
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "Laser-stripe scanner firmware and planar-part recognition")
set(CPACK_GENERATOR DEB)
set(CPACK_DEB_COMPONENT_INSTALL ON)
set(CPACK_COMPONENTS_ALL firmware)
set(CPACK_DEBIAN_FIRMWARE_PACKAGE_NAME facetscan-fw)
set(CPACK_DEBIAN_FIRMWARE_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_FIRMWARE_PACKAGE_SECTION misc)
set(CPACK_DEBIAN_FIRMWARE_PACKAGE_SHLIBDEPS OFF)
set(CPACK_DEBIAN_FIRMWARE_PACKAGE_DEPENDS "libgpiod2 (>= 1.6), libpng16-16, libfmt9, adduser")
set(CPACK_DEBIAN_FIRMWARE_PACKAGE_CONTROL_EXTRA ${PROJECT_SOURCE_DIR}/toolchain/deploy/postinst)
if(CMAKE_CROSSCOMPILING)
  if(CMAKE_SYSTEM_PROCESSOR STREQUAL "aarch64")
    set(CPACK_DEBIAN_PACKAGE_ARCHITECTURE arm64)
  elseif(CMAKE_SYSTEM_PROCESSOR MATCHES "^arm")
    set(CPACK_DEBIAN_PACKAGE_ARCHITECTURE armhf)
  endif()
endif()
include(CPack)
