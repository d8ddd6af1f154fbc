# One ctest test per GoogleTest suite of a LibTorch test executable, instead of one per test
# (gtest_discover_tests): every process of such an executable pays LibTorch's start-up, 0.6 s of
# operator registration, so a test per process spent more in start-ups than in the tests
# (docs/benchmarks.md, "CI on a fresh machine"). Names are <folder>.<Suite>; a failure's output
# names the test that failed. A suite whose every test skips is reported as skipped.
#
#   ii_add_test_suites(<target> <prefix> <working directory>)
# After each build of <target>, the script mode of this file lists its tests and writes the
# ctest file that the test directory includes.
if(CMAKE_SCRIPT_MODE_FILE)
  execute_process(COMMAND ${EXE} --gtest_list_tests WORKING_DIRECTORY ${WORKDIR} TIMEOUT 60
    OUTPUT_VARIABLE listing RESULT_VARIABLE status)
  if(NOT status EQUAL 0)
    message(FATAL_ERROR "${EXE} --gtest_list_tests failed (${status}): ${listing}")
  endif()
  string(REPLACE "\n" ";" lines "${listing}")
  set(suites)
  foreach(line ${lines})
    if(line MATCHES "^([A-Za-z0-9_/]+)\\.")  # a suite (its tests are indented below it)
      set(suite ${CMAKE_MATCH_1})
      list(APPEND suites ${suite})
      set(count_${suite} 0)
    elseif(line MATCHES "^  [A-Za-z0-9_/]+" AND suite)
      math(EXPR count_${suite} "${count_${suite}} + 1")
    endif()
  endforeach()
  set(content "")
  foreach(suite ${suites})
    set(name ${PREFIX}${suite})
    string(APPEND content "add_test([=[${name}]=] [==[${EXE}]==] [=[--gtest_filter=${suite}.*]=])\n"
      "set_tests_properties([=[${name}]=] PROPERTIES WORKING_DIRECTORY [==[${WORKDIR}]==] "
      "SKIP_REGULAR_EXPRESSION [=[\\[  SKIPPED \\] ${count_${suite}} tests?, listed below]=] "
      "ENVIRONMENT [=[${ENVIRONMENT}]=])\n")
  endforeach()
  file(WRITE ${OUT}.tmp "${content}")
  file(RENAME ${OUT}.tmp ${OUT})
  return()
endif()

set(II_GTEST_SUITES_SCRIPT ${CMAKE_CURRENT_LIST_FILE})
function(ii_add_test_suites target prefix workdir)
  set(listing ${CMAKE_CURRENT_BINARY_DIR}/${target}_suites.cmake)
  set(include_file ${CMAKE_CURRENT_BINARY_DIR}/${target}_suites_include.cmake)
  add_custom_command(TARGET ${target} POST_BUILD
    COMMAND ${CMAKE_COMMAND} -DEXE=$<TARGET_FILE:${target}> -DPREFIX=${prefix} -DWORKDIR=${workdir}
            "-DENVIRONMENT=${II_TEST_ENVIRONMENT}"
            -DOUT=${listing} -P ${II_GTEST_SUITES_SCRIPT}
    BYPRODUCTS ${listing} VERBATIM)
  file(WRITE ${include_file} "if(EXISTS [==[${listing}]==])\n  include([==[${listing}]==])\nelse()\n"
    "  add_test(${target}_NOT_BUILT ${target}_NOT_BUILT)\nendif()\n")
  set_property(DIRECTORY APPEND PROPERTY TEST_INCLUDE_FILES ${include_file})
endfunction()
