# gissar_library(NAME <module> SRCS ... [PUBLIC_DEPS ...] [PRIVATE_DEPS ...])
# One static library per module: target gissar_<module>. Modules only see the
# modules they list, which enforces util -> geo -> scene -> material -> sensor
# -> render -> image -> mvg -> nav -> cli.
function(gissar_library)
  cmake_parse_arguments(ARG "" "NAME" "SRCS;PUBLIC_DEPS;PRIVATE_DEPS" ${ARGN})
  add_library(gissar_${ARG_NAME} STATIC ${ARG_SRCS})
  target_include_directories(gissar_${ARG_NAME} PUBLIC ${PROJECT_SOURCE_DIR}/src)
  target_link_libraries(gissar_${ARG_NAME} PUBLIC ${ARG_PUBLIC_DEPS} PRIVATE ${ARG_PRIVATE_DEPS})
endfunction()

# gissar_test(NAME <name> SRCS ... DEPS ...): a GoogleTest executable
# registered with CTest, test data found through gissar/util/testing.h.
function(gissar_test)
  cmake_parse_arguments(ARG "" "NAME" "SRCS;DEPS" ${ARGN})
  if(NOT GISSAR_BUILD_TESTS)
    return()
  endif()
  add_executable(${ARG_NAME} ${ARG_SRCS})
  target_link_libraries(${ARG_NAME} PRIVATE ${ARG_DEPS} gissar_testing GTest::gtest_main)
  set_target_properties(${ARG_NAME} PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${CMAKE_BINARY_DIR}/tests)
  gtest_discover_tests(${ARG_NAME} DISCOVERY_TIMEOUT 60 PROPERTIES TIMEOUT 600 LABELS ${ARG_NAME})
endfunction()
