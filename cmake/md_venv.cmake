# The project venv at configure time (included by the top CMakeLists.txt for
# host builds). MD_PYTHON is the project venv's python unless given: then it is
# made or refreshed by scripts/setup-venv.sh when missing or stale; a
# different MD_PYTHON is only checked. Either failure stops the configure step
# with what to run. Changing a requirements file re-runs this at the next build.
set(md_setup_venv "${PROJECT_SOURCE_DIR}/scripts/setup-venv.sh")
set_property(DIRECTORY APPEND PROPERTY CMAKE_CONFIGURE_DEPENDS
    "${PROJECT_SOURCE_DIR}/requirements.txt" "${PROJECT_SOURCE_DIR}/python/pyproject.toml")
if(EXISTS "${PROJECT_SOURCE_DIR}/tests/python/requirements.txt")
    set_property(DIRECTORY APPEND PROPERTY CMAKE_CONFIGURE_DEPENDS "${PROJECT_SOURCE_DIR}/tests/python/requirements.txt")
endif()

if(MD_PYTHON STREQUAL md_venv_python)
    execute_process(COMMAND "${md_setup_venv}" --check RESULT_VARIABLE md_venv_rc ERROR_VARIABLE md_venv_why
                    OUTPUT_QUIET)
    if(NOT md_venv_rc EQUAL 0)
        string(STRIP "${md_venv_why}" md_venv_why)
        message(STATUS "Project venv: ${md_venv_why}; making it now (scripts/setup-venv.sh: PyPI packages of "
                       "requirements.txt and python/, a few minutes the first time)")
        execute_process(COMMAND "${md_setup_venv}" RESULT_VARIABLE md_venv_rc)
        if(NOT md_venv_rc EQUAL 0)
            message(FATAL_ERROR "The project venv ${md_venv_python} could not be made (scripts/setup-venv.sh exit "
                                "${md_venv_rc}, output above). The Python tests and microdrive-session's report "
                                "and plots need it. Fix the cause and run scripts/setup-venv.sh (on Debian/Ubuntu "
                                "scripts/test.sh installs the system packages first), or configure with "
                                "-DMD_PYTHON=/path/to/python where requirements.txt and python/ are installed.")
        endif()
    endif()
    message(STATUS "Project venv: ${md_venv_python}")
elseif(NOT EXISTS "${MD_PYTHON}")
    message(FATAL_ERROR "MD_PYTHON=${MD_PYTHON} does not exist. Give an interpreter where requirements.txt and "
                        "python/ are installed, or leave MD_PYTHON unset to use the project venv "
                        "(made by scripts/setup-venv.sh).")
else()
    message(STATUS "Python for tests and tools: ${MD_PYTHON} (not the project venv: not checked)")
endif()
