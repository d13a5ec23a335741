# ctest <module>/SuitesCoverEveryTest (geodrive_add_test ONE_PROCESS_PER_SUITE): every test suite
# the GoogleTest executable BINARY holds is one of SUITES (the CTest entries, one per suite, read
# from the sources at configure time), so no test is left out of the CTest run.
# Usage: cmake -DBINARY=<executable> -DSUITES=<suite;suite;...> -P check_test_suites.cmake
cmake_policy(SET CMP0057 NEW)  # if(IN_LIST)
execute_process(COMMAND ${BINARY} --gtest_list_tests
  OUTPUT_VARIABLE listing RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "${BINARY} --gtest_list_tests failed (exit ${rc})")
endif()
string(REPLACE "\n" ";" lines "${listing}")
set(held 0)
set(missing)
foreach(line IN LISTS lines)
  # Suite lines are "Suite." at column 0; test lines are indented.
  if(line MATCHES "^([A-Za-z0-9_/]+)\\.$")
    math(EXPR held "${held} + 1")
    if(NOT CMAKE_MATCH_1 IN_LIST SUITES)
      list(APPEND missing ${CMAKE_MATCH_1})
    endif()
  endif()
endforeach()
if(missing)
  message(FATAL_ERROR "suites without a CTest entry (not run by ctest): ${missing}; "
                      "declare their tests with TEST/TEST_F at the start of a line")
endif()
if(held EQUAL 0)
  message(FATAL_ERROR "${BINARY} lists no test suite")
endif()
message(STATUS "${held} suites, each a CTest entry")
