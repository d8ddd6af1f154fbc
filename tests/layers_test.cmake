# The build's include check (cmake/check_layer.cmake) on a made-up tree: an include of a
# folder that is not linked fails with the file and the line; allowed ones pass.
file(REMOVE_RECURSE ${WORK})
file(WRITE ${WORK}/src/io/reader.cpp "#include \"common/error.h\"\n#include <vector>\n#include \"io/reader.h\"\n")
file(WRITE ${WORK}/src/io/bad.h "#pragma once\n  #  include \"model/network.h\"\n")
file(MAKE_DIRECTORY ${WORK}/src/common ${WORK}/src/model)
execute_process(COMMAND ${CMAKE_COMMAND} -DROOT=${WORK}/src -DFOLDER=io -DALLOWED=io,common -DSTAMP=${WORK}/io.ok
                        -P ${SCRIPT}
                RESULT_VARIABLE rc ERROR_VARIABLE err)
if(rc EQUAL 0 OR NOT err MATCHES "src/io may include only io,common" OR NOT err MATCHES "src/io/bad.h: #  include \"model/network.h\"")
  message(FATAL_ERROR "an upward include was not refused as expected (exit ${rc}):\n${err}")
endif()
if(err MATCHES "reader.cpp")
  message(FATAL_ERROR "an allowed include was refused:\n${err}")
endif()
file(REMOVE ${WORK}/src/io/bad.h)
execute_process(COMMAND ${CMAKE_COMMAND} -DROOT=${WORK}/src -DFOLDER=io -DALLOWED=io,common -DSTAMP=${WORK}/io.ok
                        -P ${SCRIPT}
                RESULT_VARIABLE rc ERROR_VARIABLE err)
if(NOT rc EQUAL 0 OR NOT EXISTS ${WORK}/io.ok)
  message(FATAL_ERROR "allowed includes were refused (exit ${rc}):\n${err}")
endif()
