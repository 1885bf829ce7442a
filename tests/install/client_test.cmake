# The C++ reference client (tools/trackers/cpp): built against the installed package with
# find_package(linksight), run by `linksight run --tracker` beside the built-in chain-fit
# on the same frames. Same library, same frames, same settings: the same scores, which
# proves both the installed package and the protocol (every node crosses it as JSON).
file(REMOVE_RECURSE ${WORK_DIR})
execute_process(COMMAND ${CMAKE_COMMAND} --install ${BUILD_DIR} --prefix ${WORK_DIR}/prefix
                COMMAND_ERROR_IS_FATAL ANY OUTPUT_QUIET)
execute_process(COMMAND ${CMAKE_COMMAND} -S ${SOURCE_DIR} -B ${WORK_DIR}/build
                        -DCMAKE_PREFIX_PATH=${WORK_DIR}/prefix -DCMAKE_CXX_COMPILER=${CXX}
                        -DCMAKE_BUILD_TYPE=Release
                COMMAND_ERROR_IS_FATAL ANY OUTPUT_QUIET)
execute_process(COMMAND ${CMAKE_COMMAND} --build ${WORK_DIR}/build COMMAND_ERROR_IS_FATAL ANY
                OUTPUT_QUIET)
execute_process(COMMAND ${LINKSIGHT} run ${SCENE} --frames 12 --set tracker.base_prior.enabled=true
                        --tracker cf=${WORK_DIR}/build/chain_fit_client --compare chain-fit,cf
                        --no-figures --quiet --out ${WORK_DIR}/run
                RESULT_VARIABLE rc ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "linksight run with the client failed (${rc}): ${err}")
endif()
file(READ ${WORK_DIR}/run/summary.json summary)
foreach(metric node_err_mean_mm node_err_max_mm sdf_err_mean_mm swaps lost_frames)
  string(JSON built_in GET "${summary}" modes chain-fit ${metric})
  string(JSON client GET "${summary}" modes cf ${metric})
  message(STATUS "${metric}: chain-fit ${built_in}, client ${client}")
  if(NOT built_in STREQUAL client)
    message(FATAL_ERROR "${metric}: the client's ${client} differs from chain-fit's ${built_in}")
  endif()
endforeach()
file(READ ${WORK_DIR}/run/nodes.csv nodes)
string(REGEX MATCHALL "\ncf,[^\n]*" rows "${nodes}")
list(LENGTH rows n)
if(NOT n EQUAL 144)
  message(FATAL_ERROR "expected 12 frames x 12 nodes of the client, got ${n} rows")
endif()
