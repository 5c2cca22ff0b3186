# Debian packages (CPack DEB), one per program, from the install components of
# cmake/forestmap_install.cmake:
#   forestmapd  /usr/bin/forestmapd, its systemd unit with a drop-in naming the package's system
#               user, the conffiles /etc/forestmapd/forestmapd.conf (every setting, commented out;
#               readable by the service's group) and forestmapd.env (root-only, for secrets such
#               as a PostgreSQL URL with a password), and maintainer scripts that make the user
#               `forestmapd` and /var/lib/forestmapd (deploy/debian/)
#   forestmap   /usr/bin/forestmap, the client CLI
# Their Depends come from the binaries (dpkg-shlibdeps, in dpkg-dev). Build them with
# `bash deploy/package.sh`, or `cpack --config BUILD/CPackConfig.cmake` after a build.
# The lab and the client library (components lab, dev) are not packaged.
set(FORESTMAP_PACKAGES "")
if(FORESTMAP_BUILD_SERVER)
  list(APPEND FORESTMAP_PACKAGES forestmapd)
  # Installed only into the package (EXCLUDE_FROM_ALL: `cmake --install` without --component
  # skips them), where the postinst makes the user and /etc is the system's.
  set(debian ${PROJECT_SOURCE_DIR}/deploy/debian)
  install(FILES ${debian}/forestmapd.env DESTINATION /etc/forestmapd
    PERMISSIONS OWNER_READ OWNER_WRITE COMPONENT forestmapd EXCLUDE_FROM_ALL)
  install(FILES ${PROJECT_SOURCE_DIR}/deploy/forestmapd.conf DESTINATION /etc/forestmapd
    PERMISSIONS OWNER_READ OWNER_WRITE GROUP_READ COMPONENT forestmapd EXCLUDE_FROM_ALL)
  install(FILES ${debian}/forestmapd-user.conf
    DESTINATION lib/systemd/system/forestmapd.service.d COMPONENT forestmapd EXCLUDE_FROM_ALL)
  file(WRITE ${PROJECT_BINARY_DIR}/debian/conffiles
    "/etc/forestmapd/forestmapd.conf\n/etc/forestmapd/forestmapd.env\n")
  set(CPACK_DEBIAN_FORESTMAPD_PACKAGE_CONTROL_EXTRA ${debian}/postinst ${debian}/prerm
    ${debian}/postrm ${PROJECT_BINARY_DIR}/debian/conffiles)
  set(CPACK_DEBIAN_FORESTMAPD_PACKAGE_DEPENDS "adduser")  # + dpkg-shlibdeps' list
  set(CPACK_DEBIAN_FORESTMAPD_PACKAGE_RECOMMENDS "forestmap")  # `forestmap health`
  string(CONCAT CPACK_COMPONENT_FORESTMAPD_DESCRIPTION
    "ForestMap map server (forestmapd)\n"
    "Serves forest tree maps over gRPC: map versions, uploads from drones and relocalization of\n"
    "a scan's trees in a map; SQLite or PostgreSQL storage. A systemd service listening on\n"
    "127.0.0.1:50051, configured in /etc/forestmapd/forestmapd.conf.")
endif()
if(FORESTMAP_BUILD_CLIENT)
  list(APPEND FORESTMAP_PACKAGES forestmap)
  string(CONCAT CPACK_COMPONENT_FORESTMAP_DESCRIPTION
    "ForestMap client (forestmap)\n"
    "Command line client of forestmapd: manage tree maps, upload surveys and drone detections,\n"
    "detect trunks in LiDAR scans and relocalize them, export maps to GIS formats.")
endif()
if(NOT FORESTMAP_PACKAGES)
  return()
endif()

set(CPACK_GENERATOR DEB)
# cpack packages what was built and builds nothing (deploy/package.sh builds first): without
# this its `preinstall` step would build every target, tests included.
set(CMAKE_SKIP_INSTALL_ALL_DEPENDENCY ON)
set(CPACK_PACKAGE_NAME forestmap)
set(CPACK_PACKAGE_VENDOR "ForestMap")
set(CPACK_PACKAGE_CONTACT "ForestMap maintainers <forestmap@localhost>")
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_COMPONENTS_ALL ${FORESTMAP_PACKAGES})
set(CPACK_DEB_COMPONENT_INSTALL ON)
# Install with DESTDIR and the real prefix, so that the unit's ExecStart (cmake/install_unit.cmake)
# and /etc/forestmapd are the installed system's paths, not the staging folder's.
set(CPACK_SET_DESTDIR ON)
set(CPACK_INSTALL_PREFIX /usr)
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_STRIP_FILES ON)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)  # NAME_VERSION_ARCH.deb
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
set(CPACK_DEBIAN_PACKAGE_SECTION science)
set(CPACK_DEBIAN_PACKAGE_CONTROL_STRICT_PERMISSION ON)
set(CPACK_DEBIAN_FORESTMAPD_PACKAGE_NAME forestmapd)
set(CPACK_DEBIAN_FORESTMAP_PACKAGE_NAME forestmap)
include(CPack)
