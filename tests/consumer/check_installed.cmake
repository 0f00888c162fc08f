# ctest -P script: installs the build tree into a fresh prefix and configures, builds and runs
# tests/consumer/installed against it with find_package(progiso COMPONENTS ${COMPONENTS}).
# Fails when the configure prints a warning, when a component loads a dependency it does not
# need (${MUST_NOT_FIND}: packages that must not be found), or when the program fails.
# Arguments: -DBUILD_DIR= -DSOURCE_DIR= -DWORK_DIR= -DCOMPONENTS=a,b -DMUST_NOT_FIND=X,Y
file(REMOVE_RECURSE "${WORK_DIR}")
execute_process(COMMAND ${CMAKE_COMMAND} --install "${BUILD_DIR}" --prefix "${WORK_DIR}/prefix"
                RESULT_VARIABLE rc OUTPUT_QUIET ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "cmake --install failed: ${err}")
endif()
set(components "${COMPONENTS}")
string(REPLACE "," ";" MUST_NOT_FIND "${MUST_NOT_FIND}")
execute_process(COMMAND ${CMAKE_COMMAND} -S "${SOURCE_DIR}" -B "${WORK_DIR}/build" -G Ninja
                        "-DCMAKE_PREFIX_PATH=${WORK_DIR}/prefix" "-DPROGISO_COMPONENTS=${components}"
                RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "configuring the consumer failed:\n${out}\n${err}")
endif()
if(err MATCHES "[Ww]arning" OR out MATCHES "CMake Warning|does not exist")
  message(FATAL_ERROR "configuring the consumer printed warnings:\n${out}\n${err}")
endif()
foreach(package IN LISTS MUST_NOT_FIND)
  if(out MATCHES "consumer: found ${package}")
    message(FATAL_ERROR "find_package(progiso COMPONENTS ${COMPONENTS}) looked for ${package}")
  endif()
endforeach()
execute_process(COMMAND ${CMAKE_COMMAND} --build "${WORK_DIR}/build"
                RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "building the consumer failed:\n${out}\n${err}")
endif()
execute_process(COMMAND "${WORK_DIR}/build/consumer" "${WORK_DIR}"
                RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(NOT rc EQUAL 0 OR NOT out MATCHES "consumer: ok")
  message(FATAL_ERROR "the consumer failed (${rc}):\n${out}\n${err}")
endif()
message(STATUS "consumer with components ${COMPONENTS}: ok")
