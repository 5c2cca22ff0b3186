# What `cmake --install BUILD [--prefix DIR]` puts where (GNU layout under the prefix):
#   bin/forestmapd, bin/forestmap, bin/forestmap-lab    the programs that were built
#   lib/systemd/system/forestmapd.service               the service unit (with the server)
#   lib/libforestmap_{client,io,proto,detection,core}.a the client library and what it links
#   include/forestmap/...                                its headers, under the paths the code
#                                                        includes ("client/lib/forestmap_client.h")
#   lib/cmake/ForestMap/                                 find_package(ForestMap CONFIG):
#                                                        ForestMap::client
#   lib/pkgconfig/forestmap-client.pc                    the same for pkg-config users
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

if(FORESTMAP_BUILD_SERVER)
  install(TARGETS forestmapd RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
  install(FILES deploy/forestmapd.service DESTINATION lib/systemd/system)
endif()
if(FORESTMAP_BUILD_LAB)
  install(TARGETS forestmap-lab RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
endif()
if(NOT FORESTMAP_BUILD_CLIENT)
  return()
endif()
install(TARGETS forestmap RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})

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
