# Run after a GoogleTest program is built (forestmap_discover_tests in tests/CMakeLists.txt):
# lists its tests and writes CTEST_FILE, one CTest test per test suite (`Suite` or
# `Prefix/Suite` of a parameterized one), which runs the program with --gtest_filter=Suite.*
# through tests/tools/run_suite.sh (skipped when every test of the suite skipped).
# A suite's tests run one after the other in one process: a program that links the server starts
# in up to 0.6 CPU-s under the sanitizers, and the suites still run in parallel.
# Variables: EXECUTABLE, RUN_SUITE (tests/tools/run_suite.sh), WORKING_DIR, CTEST_FILE, LABELS
# (a list), REAL_DATA_SUITES (the suites that read the real data: they also get the label
# real_data), PROPERTIES (further test properties: name, value, name, value...; no value holds
# a ";").
cmake_policy(VERSION 3.22)
execute_process(COMMAND "${EXECUTABLE}" --gtest_list_tests
  WORKING_DIRECTORY "${WORKING_DIR}" TIMEOUT 60
  OUTPUT_VARIABLE listing ERROR_VARIABLE errors RESULT_VARIABLE status)
if(NOT status EQUAL 0)
  file(REMOVE "${CTEST_FILE}")
  message(FATAL_ERROR "${EXECUTABLE} --gtest_list_tests failed (${status}):\n${listing}${errors}")
endif()

set(script "")
string(REPLACE "\n" ";" lines "${listing}")
foreach(line IN LISTS lines)
  # A suite's line starts in the first column: "Suite." or "Prefix/Suite.  # TypeParam = ...".
  if(NOT line MATCHES "^([^ #][^ ]*)\\.")
    continue()
  endif()
  set(suite "${CMAKE_MATCH_1}")
  set(suite_labels ${LABELS})
  string(REGEX REPLACE "^[^/]+/" "" plain_suite "${suite}")
  if(plain_suite IN_LIST REAL_DATA_SUITES)
    list(APPEND suite_labels real_data)
  endif()
  list(JOIN suite_labels "\\;" suite_labels)
  string(APPEND script
    "add_test([==[${suite}]==] [==[${RUN_SUITE}]==] [==[${EXECUTABLE}]==] [==[${suite}]==])\n"
    "set_tests_properties([==[${suite}]==] PROPERTIES WORKING_DIRECTORY [==[${WORKING_DIR}]==]\n"
    "  LABELS \"${suite_labels}\" SKIP_RETURN_CODE 77")
  set(key "")
  foreach(item IN LISTS PROPERTIES)
    if(key STREQUAL "")
      set(key "${item}")
    else()
      string(APPEND script " ${key} [==[${item}]==]")
      set(key "")
    endif()
  endforeach()
  string(APPEND script ")\n")
endforeach()
file(WRITE "${CTEST_FILE}" "${script}")
