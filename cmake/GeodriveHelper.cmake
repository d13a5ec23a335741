# geodrive_add_library(NAME <target> [SRCS ...] [PUBLIC_LINK_LIBS ...] [PRIVATE_LINK_LIBS ...]
#                      [PRIVATE_HEADERS ...])
#
# Declares one static library per module folder. Sources default to every *.cc in the folder;
# headers (*.h, excluding internal/ and PRIVATE_HEADERS) are installed under
# include/geodrive/<path from the repository root>/ (e.g. geometry/util/). The target is
# exported as geodrive::<folder> (e.g. geodrive::geometry, geodrive::util). Every installed header
# is a public header: tests/install checks that each compiles alone and pulls in no PCL, Ceres,
# nlohmann_json or LibTorch header.
function(geodrive_add_library)
  cmake_parse_arguments(ARG "" "NAME" "SRCS;PUBLIC_LINK_LIBS;PRIVATE_LINK_LIBS;PRIVATE_HEADERS" ${ARGN})
  get_filename_component(folder ${CMAKE_CURRENT_SOURCE_DIR} NAME)
  file(RELATIVE_PATH include_subdir ${PROJECT_SOURCE_DIR} ${CMAKE_CURRENT_SOURCE_DIR})
  if(NOT ARG_SRCS)
    file(GLOB ARG_SRCS CONFIGURE_DEPENDS ${CMAKE_CURRENT_SOURCE_DIR}/*.cc)
  endif()
  file(GLOB headers CONFIGURE_DEPENDS ${CMAKE_CURRENT_SOURCE_DIR}/*.h)
  foreach(h ${ARG_PRIVATE_HEADERS})
    list(REMOVE_ITEM headers ${CMAKE_CURRENT_SOURCE_DIR}/${h})
  endforeach()
  set_property(GLOBAL APPEND PROPERTY GEODRIVE_PUBLIC_HEADERS ${headers})
  add_library(${ARG_NAME} STATIC ${ARG_SRCS})
  add_library(geodrive::${folder} ALIAS ${ARG_NAME})
  set_target_properties(${ARG_NAME} PROPERTIES EXPORT_NAME ${folder})
  target_include_directories(${ARG_NAME} PUBLIC
    $<BUILD_INTERFACE:${PROJECT_SOURCE_DIR}>
    $<BUILD_INTERFACE:${PROJECT_BINARY_DIR}/generated>
    $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}/geodrive>)
  target_compile_options(${ARG_NAME} PRIVATE ${GEODRIVE_WARNINGS})
  if(GEODRIVE_FUZZ AND ARG_NAME IN_LIST GEODRIVE_FUZZ_COVERAGE_LIBS)
    target_compile_options(${ARG_NAME} PRIVATE -fsanitize=fuzzer-no-link)
  endif()
  target_link_libraries(${ARG_NAME} PUBLIC ${ARG_PUBLIC_LINK_LIBS} PRIVATE ${ARG_PRIVATE_LINK_LIBS})
  install(TARGETS ${ARG_NAME} EXPORT geodriveTargets
    ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
    LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR})
  install(FILES ${headers} DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/geodrive/${include_subdir})
endfunction()

# geodrive_add_test(MODULE <module> [SRCS ...] LINK_LIBS ... [ENVIRONMENT VAR=value]
#                   [ONE_PROCESS_PER_SUITE])
#
# One GoogleTest executable per module (tests/<module>/*_test.cc by default), linked to the shared
# seeded test main; each TEST becomes a CTest test named <module>/<Suite>.<Name>, labelled <module>,
# run with ENVIRONMENT (one VAR=value) when given. With ONE_PROCESS_PER_SUITE, and in sanitizer
# builds (GEODRIVE_SANITIZE), each test suite is one CTest test instead, <module>/<Suite>
# (--gtest_filter=<Suite>.*), where a process costs more to start than most tests take
# (LibTorch's operator registry: 0.7 s; ASan's shadow memory and LeakSanitizer's exit scan:
# 0.35 s); GEODRIVE_TESTS_LEFT_OUT (a negative --gtest_filter pattern) is left out of them. The
# suites are read from the sources' TEST/TEST_F lines, and <module>/SuitesCoverEveryTest fails
# when the executable holds a test that no suite entry runs.
function(geodrive_add_test)
  cmake_parse_arguments(ARG "ONE_PROCESS_PER_SUITE" "MODULE;ENVIRONMENT" "SRCS;LINK_LIBS" ${ARGN})
  if(NOT ARG_SRCS)
    file(GLOB ARG_SRCS CONFIGURE_DEPENDS ${CMAKE_CURRENT_SOURCE_DIR}/*_test.cc)
  endif()
  if(NOT ARG_SRCS)
    message(STATUS "geodrive: no tests yet for module ${ARG_MODULE}")
    return()
  endif()
  set(target geodrive_${ARG_MODULE}_tests)
  add_executable(${target} ${ARG_SRCS})
  target_compile_options(${target} PRIVATE ${GEODRIVE_WARNINGS})
  target_link_libraries(${target} PRIVATE geodrive_test_main ${ARG_LINK_LIBS})
  set(props LABELS ${ARG_MODULE})
  if(ARG_ENVIRONMENT)
    list(APPEND props ENVIRONMENT ${ARG_ENVIRONMENT})
  endif()
  if(NOT ARG_ONE_PROCESS_PER_SUITE AND NOT GEODRIVE_SANITIZE)
    gtest_discover_tests(${target}
      TEST_PREFIX "${ARG_MODULE}/"
      PROPERTIES ${props}
      DISCOVERY_MODE PRE_TEST
      DISCOVERY_TIMEOUT 60)
    return()
  endif()
  # A new suite in a source re-runs the configure step.
  set_property(DIRECTORY APPEND PROPERTY CMAKE_CONFIGURE_DEPENDS ${ARG_SRCS})
  set(suites)
  foreach(src IN LISTS ARG_SRCS)
    file(STRINGS ${src} lines REGEX "^TEST(_F)?\\( *[A-Za-z0-9_]+ *,")
    foreach(line IN LISTS lines)
      string(REGEX REPLACE "^TEST(_F)?\\( *([A-Za-z0-9_]+).*" "\\2" suite "${line}")
      list(APPEND suites ${suite})
    endforeach()
  endforeach()
  list(REMOVE_DUPLICATES suites)
  foreach(suite IN LISTS suites)
    set(filter ${suite}.*)
    if(GEODRIVE_TESTS_LEFT_OUT)
      string(APPEND filter -${GEODRIVE_TESTS_LEFT_OUT})
    endif()
    add_test(NAME ${ARG_MODULE}/${suite} COMMAND ${target} --gtest_filter=${filter})
    set_tests_properties(${ARG_MODULE}/${suite} PROPERTIES ${props})
  endforeach()
  add_test(NAME ${ARG_MODULE}/SuitesCoverEveryTest
    COMMAND ${CMAKE_COMMAND} -DBINARY=$<TARGET_FILE:${target}> "-DSUITES=${suites}"
            -P ${PROJECT_SOURCE_DIR}/cmake/check_test_suites.cmake)
  set_tests_properties(${ARG_MODULE}/SuitesCoverEveryTest PROPERTIES ${props})
endfunction()

# geodrive_add_plugin(NAME <target> FILE_NAME <stem> SRCS ... [LINK_LIBS ...])
#
# A shared-library plugin (geometry/util/plugin.h), loaded with dlopen on first use: built as
# <build>/lib/geodrive/lib<stem>.so and installed in <libdir>/geodrive. Only symbols marked
# visibility("default") (the plugin's entry point) are exported: the static libraries linked in
# stay private to the plugin (--exclude-libs) and bind to themselves (-Bsymbolic), so a plugin and
# the executable that loads it can both hold the toolkit's libraries without mixing them.
function(geodrive_add_plugin)
  cmake_parse_arguments(ARG "" "NAME;FILE_NAME" "SRCS;LINK_LIBS" ${ARGN})
  add_library(${ARG_NAME} MODULE ${ARG_SRCS})
  set_target_properties(${ARG_NAME} PROPERTIES
    OUTPUT_NAME ${ARG_FILE_NAME}
    LIBRARY_OUTPUT_DIRECTORY ${GEODRIVE_PLUGIN_BUILD_DIR}
    CXX_VISIBILITY_PRESET hidden
    VISIBILITY_INLINES_HIDDEN ON)
  target_compile_options(${ARG_NAME} PRIVATE ${GEODRIVE_WARNINGS})
  target_include_directories(${ARG_NAME} PRIVATE ${PROJECT_SOURCE_DIR}
    ${PROJECT_BINARY_DIR}/generated)
  target_link_options(${ARG_NAME} PRIVATE -Wl,--exclude-libs,ALL -Wl,-Bsymbolic)
  if(NOT GEODRIVE_SANITIZE AND NOT GEODRIVE_FUZZ)
    # A symbol left undefined would only fail at dlopen, in front of a user: fail the link instead
    # (sanitizer builds leave the sanitizer runtime to the executable, so they cannot).
    target_link_options(${ARG_NAME} PRIVATE -Wl,--no-undefined)
  endif()
  target_link_libraries(${ARG_NAME} PRIVATE ${ARG_LINK_LIBS})
  install(TARGETS ${ARG_NAME} LIBRARY DESTINATION ${GEODRIVE_PLUGIN_INSTALL_DIR})
endfunction()
