# cmake -DPROGRAM=<path> -DARGS=<a|b|...> -DEXPECTED_STATUS=<n> -DEXPECTED_MESSAGE=<text>
#       -P expect_refusal.cmake
# Runs PROGRAM with the '|'-separated ARGS and fails unless it exits with EXPECTED_STATUS and
# its stderr contains EXPECTED_MESSAGE (plain text, not a regular expression).
foreach(var PROGRAM EXPECTED_STATUS EXPECTED_MESSAGE)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "expect_refusal.cmake: ${var} is not set")
  endif()
endforeach()
string(REPLACE "|" ";" args "${ARGS}")
execute_process(COMMAND ${PROGRAM} ${args} RESULT_VARIABLE status OUTPUT_VARIABLE out
                ERROR_VARIABLE err TIMEOUT 20)
string(FIND "${err}" "${EXPECTED_MESSAGE}" at)
if(NOT status STREQUAL EXPECTED_STATUS OR at EQUAL -1)
  message(FATAL_ERROR "${PROGRAM} ${args}: expected exit status ${EXPECTED_STATUS} and "
                      "'${EXPECTED_MESSAGE}' on stderr, got status ${status}\n"
                      "stderr:\n${err}\nstdout:\n${out}")
endif()
message(STATUS "${PROGRAM} ${args}: refused (status ${status}): ${err}")
