# Runs `cellflow-run SPEC -o OUT --quiet --threads 1` and checks exit code 0, the CSV
# header and the number of data rows. Arguments: RUNNER, SPEC, OUT, ROWS.
# One thread: ctest runs tests side by side on a 2-core machine.
execute_process(COMMAND ${RUNNER} ${SPEC} -o ${OUT} --quiet --threads 1 RESULT_VARIABLE code ERROR_VARIABLE err)
if(NOT code EQUAL 0)
  message(FATAL_ERROR "cellflow-run exited with ${code}: ${err}")
endif()
file(STRINGS ${OUT} lines)
list(LENGTH lines count)
list(GET lines 0 header)
set(expected "point,deformation,displacement_m,force_n,hertz_force_n,force_over_hertz,taylor_deformation,a1_m,a2_m,a3_m,volume_m3,elastic_energy_j,max_penetration_m,newton_iterations,step_splits,residual")
if(NOT header STREQUAL expected)
  message(FATAL_ERROR "unexpected header: ${header}")
endif()
math(EXPR data_rows "${count} - 1")
if(NOT data_rows EQUAL ${ROWS})
  message(FATAL_ERROR "expected ${ROWS} data rows, got ${data_rows}")
endif()
message(STATUS "cellflow-run: exit 0, header ok, ${data_rows} rows")
