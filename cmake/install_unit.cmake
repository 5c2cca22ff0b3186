# Installs deploy/forestmapd.service into PREFIX/lib/systemd/system with its ExecStart naming
# PREFIX/BINDIR/forestmapd, the prefix of this install (run by cmake_install.cmake, where
# CMAKE_INSTALL_PREFIX is the one given to `cmake --install --prefix` or CPack's). Set before it:
# FORESTMAP_UNIT_SOURCE (the unit), FORESTMAP_UNIT_BINDIR (CMAKE_INSTALL_BINDIR),
# FORESTMAP_UNIT_STAGING (a folder of the build tree for the written unit).
if(IS_ABSOLUTE "${FORESTMAP_UNIT_BINDIR}")
  set(bindir "${FORESTMAP_UNIT_BINDIR}")
else()
  set(bindir "${CMAKE_INSTALL_PREFIX}/${FORESTMAP_UNIT_BINDIR}")
endif()
file(READ "${FORESTMAP_UNIT_SOURCE}" unit)
string(REGEX REPLACE "\nExecStart=[^ \n]*/forestmapd([ \n])" "\nExecStart=${bindir}/forestmapd\\1"
       written "${unit}")
string(FIND "${written}" "\nExecStart=${bindir}/forestmapd" at)
if(at EQUAL -1)
  message(FATAL_ERROR "${FORESTMAP_UNIT_SOURCE}: no 'ExecStart=/path/to/forestmapd' line to point "
                      "at ${bindir}/forestmapd")
endif()
# One staging folder per destination: installs to several prefixes may run at once.
string(MD5 destination "$ENV{DESTDIR}${CMAKE_INSTALL_PREFIX}")
set(staged "${FORESTMAP_UNIT_STAGING}/${destination}/forestmapd.service")
file(WRITE "${staged}" "${written}")
file(INSTALL "${staged}" DESTINATION "${CMAKE_INSTALL_PREFIX}/lib/systemd/system")
