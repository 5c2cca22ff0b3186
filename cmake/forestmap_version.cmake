# forestmap_version: the generated header forestmap_version.h (version from project(VERSION), git
# commit, build type) behind `--version` of forestmapd and forestmap. Link the target, then
#   #include "forestmap_version.h"   ...   forestmap::VersionLine("forestmap")
# The header is regenerated at every build, since the commit changes without a reconfigure, and
# rewritten only when its text changes, so nothing recompiles otherwise. A source tree without
# git (a release tarball) shows the commit "unknown" unless -DFORESTMAP_GIT_COMMIT=... says it.
set(FORESTMAP_GIT_COMMIT "" CACHE STRING "Commit shown by --version (empty: asked from git)")
set(forestmap_version_dir ${PROJECT_BINARY_DIR}/generated)
add_custom_target(forestmap_version_header
  COMMAND ${CMAKE_COMMAND} -DSOURCE_DIR=${PROJECT_SOURCE_DIR}
    -DOUTPUT=${forestmap_version_dir}/forestmap_version.h -DVERSION=${PROJECT_VERSION}
    -DBUILD_TYPE=${CMAKE_BUILD_TYPE} -DCOMMIT=${FORESTMAP_GIT_COMMIT}
    -P ${CMAKE_CURRENT_LIST_DIR}/forestmap_version_header.cmake
  BYPRODUCTS ${forestmap_version_dir}/forestmap_version.h
  VERBATIM)
add_library(forestmap_version INTERFACE)
target_include_directories(forestmap_version INTERFACE ${forestmap_version_dir})
add_dependencies(forestmap_version forestmap_version_header)
