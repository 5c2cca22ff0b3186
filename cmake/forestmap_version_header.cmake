# Writes OUTPUT from forestmap_version.h.in (cmake -P, run by the forestmap_version_header target
# of forestmap_version.cmake at every build). COMMIT empty: the checkout's HEAD, "-dirty" when
# tracked files differ from it; "unknown" outside a git checkout.
if(NOT COMMIT)
  set(COMMIT unknown)
  find_package(Git QUIET)
  if(GIT_FOUND)
    execute_process(COMMAND ${GIT_EXECUTABLE} -C ${SOURCE_DIR} rev-parse --short=12 HEAD
      OUTPUT_VARIABLE head OUTPUT_STRIP_TRAILING_WHITESPACE RESULT_VARIABLE failed ERROR_QUIET)
    if(NOT failed)
      set(COMMIT ${head})
      execute_process(COMMAND ${GIT_EXECUTABLE} -C ${SOURCE_DIR} diff --quiet HEAD --
        RESULT_VARIABLE dirty ERROR_QUIET)
      if(dirty)
        string(APPEND COMMIT "-dirty")
      endif()
    endif()
  endif()
endif()
if(NOT BUILD_TYPE)
  set(BUILD_TYPE none)
endif()
configure_file(${CMAKE_CURRENT_LIST_DIR}/forestmap_version.h.in ${OUTPUT} @ONLY)
