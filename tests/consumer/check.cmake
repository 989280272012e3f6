# Installs the project's own build (BUILD_DIR, already built: its plastifem::compiled library
# included) into WORK_DIR/prefix, then configures, builds and runs tests/consumer against it
# with find_package(plastifem CONFIG REQUIRED): the header-only target and plastifem::compiled.
file(REMOVE_RECURSE ${WORK_DIR})
function(run)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "failed (${rc}): ${ARGN}")
  endif()
endfunction()
run(${CMAKE_COMMAND} --install ${BUILD_DIR} --prefix ${WORK_DIR}/prefix)
run(${CMAKE_COMMAND} -S ${SOURCE_DIR}/tests/consumer -B ${WORK_DIR}/consumer -G ${GENERATOR}
    -DCMAKE_PREFIX_PATH=${WORK_DIR}/prefix -DCMAKE_BUILD_TYPE=Release)
run(${CMAKE_COMMAND} --build ${WORK_DIR}/consumer)
run(${WORK_DIR}/consumer/consumer)
if(EXISTS ${WORK_DIR}/consumer/consumer_compiled)
  run(${WORK_DIR}/consumer/consumer_compiled)
else()
  message(FATAL_ERROR "the installed package has no plastifem::compiled")
endif()

# A header-only user: configure and install straight away, nothing built (the README's first way).
# The package then has no plastifem::compiled, and the consumer builds against the headers alone.
run(${CMAKE_COMMAND} -S ${SOURCE_DIR} -B ${WORK_DIR}/fresh -G ${GENERATOR})
run(${CMAKE_COMMAND} --install ${WORK_DIR}/fresh --prefix ${WORK_DIR}/fresh-prefix)
run(${CMAKE_COMMAND} -S ${SOURCE_DIR}/tests/consumer -B ${WORK_DIR}/fresh-consumer -G ${GENERATOR}
    -DCMAKE_PREFIX_PATH=${WORK_DIR}/fresh-prefix -DCMAKE_BUILD_TYPE=Release)
run(${CMAKE_COMMAND} --build ${WORK_DIR}/fresh-consumer)
run(${WORK_DIR}/fresh-consumer/consumer)
if(EXISTS ${WORK_DIR}/fresh-consumer/consumer_compiled)
  message(FATAL_ERROR "a package installed without building plastifem_compiled offers plastifem::compiled")
endif()
