# ctest -P script: installs the build tree into a fresh prefix and imports the installed
# package from there with the interpreter the build chose (not the build tree's copy), and checks
# that under the configured install prefix the package lands in a directory that interpreter
# searches by default.
# Arguments: -DBUILD_DIR= -DWORK_DIR= -DPYTHON= -DPACKAGE_DIR= (relative to a prefix)
#            -DINSTALL_PREFIX= (the configured CMAKE_INSTALL_PREFIX)
cmake_minimum_required(VERSION 3.25)
file(REMOVE_RECURSE "${WORK_DIR}")
execute_process(COMMAND ${CMAKE_COMMAND} --install "${BUILD_DIR}" --prefix "${WORK_DIR}/prefix"
                RESULT_VARIABLE rc OUTPUT_QUIET ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "cmake --install failed: ${err}")
endif()
set(code [=[
import os, sys
import numpy as np
import progiso
here = os.path.realpath(progiso.__file__)
assert here.startswith(os.path.realpath(sys.argv[1])), here
v, f, n, val = progiso.marching_cubes(np.arange(27, dtype=np.float32).reshape(3, 3, 3), 13.5)
assert len(f) > 0
print("installed package: ok")
]=])
execute_process(COMMAND ${CMAKE_COMMAND} -E env --unset=PYTHONPATH
                        "PYTHONPATH=${WORK_DIR}/prefix/${PACKAGE_DIR}"
                        ${PYTHON} -c "${code}" "${WORK_DIR}/prefix"
                WORKING_DIRECTORY "${WORK_DIR}"
                RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(NOT rc EQUAL 0 OR NOT out MATCHES "installed package: ok")
  message(FATAL_ERROR "importing the installed package failed (${rc}):\n${out}\n${err}")
endif()
execute_process(COMMAND ${CMAKE_COMMAND} -E env --unset=PYTHONPATH
                        ${PYTHON} -c "import os, sys; print('\\n'.join(os.path.realpath(p) for p in sys.path))"
                OUTPUT_VARIABLE paths)
get_filename_component(target "${INSTALL_PREFIX}/${PACKAGE_DIR}" REALPATH)
string(REPLACE "\n" ";" paths "${paths}")
if(NOT target IN_LIST paths)
  message(FATAL_ERROR "${PYTHON} does not search ${target}, where cmake --install puts the "
                      "package under ${INSTALL_PREFIX}")
endif()
message(STATUS "installed package: ok (default location ${target})")
