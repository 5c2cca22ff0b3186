# What `cmake --install BUILD [--prefix DIR]` puts where (GNU layout under the prefix):
#   bin/forestmapd, bin/forestmap, bin/forestmap-lab    the programs that were built
#   lib/systemd/system/forestmapd.service               the service unit (with the server), its
#                                                        ExecStart the installed bin/forestmapd
#   lib/libforestmap_{client,io,proto,detection,core}.a the client library and what it links
#   include/forestmap/...                                its headers, under the paths the code
#                                                        includes ("client/lib/forestmap_client.h")
#   lib/cmake/ForestMap/                                 find_package(ForestMap CONFIG):
#                                                        ForestMap::client
#   lib/pkgconfig/forestmap-client.pc                    the same for pkg-config users
# Install components (`cmake --install BUILD --component NAME`; the Debian packages of
# cmake/packaging.cmake are the first two): forestmapd (server and unit), forestmap (client CLI),
# lab (forestmap-lab), dev (the client library).
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

if(FORESTMAP_BUILD_SERVER)
  install(TARGETS forestmapd RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT forestmapd)
  # The unit is written at install time, when the prefix is known (`cmake --install --prefix`,
  # CPack's /usr), with ExecStart naming the forestmapd installed there.
  install(CODE "set(FORESTMAP_UNIT_SOURCE \"${PROJECT_SOURCE_DIR}/deploy/forestmapd.service\")
    set(FORESTMAP_UNIT_BINDIR \"${CMAKE_INSTALL_BINDIR}\")
    set(FORESTMAP_UNIT_STAGING \"${PROJECT_BINARY_DIR}/installed-unit\")" COMPONENT forestmapd)
  install(SCRIPT cmake/install_unit.cmake COMPONENT forestmapd)
endif()
if(FORESTMAP_BUILD_LAB)
  install(TARGETS forestmap-lab RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT lab)
endif()
if(NOT FORESTMAP_BUILD_CLIENT)
  return()
endif()
install(TARGETS forestmap RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT forestmap)
set(CMAKE_INSTALL_DEFAULT_COMPONENT_NAME dev)  # every rule below

# ---- The client library: static archives, headers, CMake package, pkg-config file ----
set(FORESTMAP_INCLUDE_DIR ${CMAKE_INSTALL_INCLUDEDIR}/forestmap)
# The libraries a program linking ForestMap::client gets, as ForestMap::<suffix>.
set(FORESTMAP_CLIENT_TARGETS
  forestmap_client forestmap_io forestmap_proto forestmap_detection forestmap_core)

# The generated API headers (forestmap/v1/*.pb.h, grpc/health/v1/*.pb.h) are in the build tree:
# the one include directory of forestmap_proto under it.
get_target_property(proto_dirs forestmap_proto INTERFACE_INCLUDE_DIRECTORIES)
foreach(dir ${proto_dirs})
  string(FIND "${dir}" "${PROJECT_BINARY_DIR}/" at)
  if(at EQUAL 0)
    install(DIRECTORY ${dir}/ DESTINATION ${FORESTMAP_INCLUDE_DIR} FILES_MATCHING PATTERN "*.pb.h")
  endif()
endforeach()
# Our headers, by folder; a stage's *_internal.h stays private.
foreach(folder client/lib client/io proto algorithms/core algorithms/detection)
  install(DIRECTORY ${folder}/ DESTINATION ${FORESTMAP_INCLUDE_DIR}/${folder}
    FILES_MATCHING PATTERN "*.h" PATTERN "*_internal.h" EXCLUDE)
endforeach()

# In the build tree these libraries include from the source and build trees; installed, from
# include/forestmap. The folders' CMakeLists name the build-tree directories; they are marked
# build-only here, where the installed ones are added.
foreach(target ${FORESTMAP_CLIENT_TARGETS})
  get_target_property(dirs ${target} INTERFACE_INCLUDE_DIRECTORIES)
  list(TRANSFORM dirs REPLACE "^(/.*)$" "$<BUILD_INTERFACE:\\1>")
  string(REGEX REPLACE "^forestmap_" "" suffix ${target})
  set_target_properties(${target} PROPERTIES INTERFACE_INCLUDE_DIRECTORIES "${dirs}"
                                             EXPORT_NAME ${suffix})
endforeach()
install(TARGETS ${FORESTMAP_CLIENT_TARGETS} EXPORT ForestMapTargets
  ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
  INCLUDES DESTINATION ${FORESTMAP_INCLUDE_DIR})

set(FORESTMAP_CMAKE_DIR ${CMAKE_INSTALL_LIBDIR}/cmake/ForestMap)
install(EXPORT ForestMapTargets NAMESPACE ForestMap:: DESTINATION ${FORESTMAP_CMAKE_DIR})
configure_package_config_file(cmake/ForestMapConfig.cmake.in
  ${PROJECT_BINARY_DIR}/ForestMapConfig.cmake INSTALL_DESTINATION ${FORESTMAP_CMAKE_DIR})
write_basic_package_version_file(${PROJECT_BINARY_DIR}/ForestMapConfigVersion.cmake
  COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/ForestMapConfig.cmake
  ${PROJECT_BINARY_DIR}/ForestMapConfigVersion.cmake DESTINATION ${FORESTMAP_CMAKE_DIR})

# pkg-config: paths relative to the .pc file, so that the prefix can move (cmake --install
# --prefix, DESTDIR).
file(RELATIVE_PATH FORESTMAP_PC_TO_PREFIX "${CMAKE_INSTALL_FULL_LIBDIR}/pkgconfig"
  "${CMAKE_INSTALL_PREFIX}")
configure_file(cmake/forestmap-client.pc.in ${PROJECT_BINARY_DIR}/forestmap-client.pc @ONLY)
install(FILES ${PROJECT_BINARY_DIR}/forestmap-client.pc
  DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig)
