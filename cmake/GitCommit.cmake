# CELLFLOW_GIT_COMMIT: the commit the build was configured from ("unknown"
# outside a git checkout), for `cellflow --version` and the creator version
# of result files; a commit or checkout re-runs CMake.
set(CELLFLOW_GIT_COMMIT "unknown")
find_package(Git QUIET)
if(GIT_FOUND)
  execute_process(COMMAND ${GIT_EXECUTABLE} rev-parse --short HEAD WORKING_DIRECTORY ${PROJECT_SOURCE_DIR}
    OUTPUT_VARIABLE git_commit OUTPUT_STRIP_TRAILING_WHITESPACE ERROR_QUIET RESULT_VARIABLE git_result)
  if(git_result EQUAL 0 AND NOT git_commit STREQUAL "")
    set(CELLFLOW_GIT_COMMIT "${git_commit}")
    foreach(git_file HEAD logs/HEAD)
      execute_process(COMMAND ${GIT_EXECUTABLE} rev-parse --path-format=absolute --git-path ${git_file}
        WORKING_DIRECTORY ${PROJECT_SOURCE_DIR} OUTPUT_VARIABLE git_path OUTPUT_STRIP_TRAILING_WHITESPACE
        ERROR_QUIET RESULT_VARIABLE git_result)
      if(git_result EQUAL 0 AND EXISTS "${git_path}")
        set_property(DIRECTORY APPEND PROPERTY CMAKE_CONFIGURE_DEPENDS "${git_path}")
      endif()
    endforeach()
  endif()
endif()
