# The Python module (python/): on by default when pybind11 (Debian pybind11-dev) is found. Not in
# sanitizer or fuzz builds, whose runtime a plain python3 cannot load. python/CMakeLists.txt makes
# the stage libraries position-independent.
option(PENUMBRA_PYTHON "Build the Python module when pybind11 is found" ON)
set(PENUMBRA_PYTHON_MODULE OFF)
if(PENUMBRA_PYTHON AND NOT PENUMBRA_SANITIZE AND NOT PENUMBRA_FUZZ)
  # Debian's interpreter, not whichever python3 comes first on PATH (pyenv, a venv).
  if(NOT Python3_EXECUTABLE AND EXISTS /usr/bin/python3)
    set(Python3_EXECUTABLE /usr/bin/python3)
  endif()
  find_package(Python3 COMPONENTS Interpreter Development.Module QUIET)
  if(Python3_FOUND)
    find_package(pybind11 CONFIG QUIET)
  endif()
  if(pybind11_FOUND)
    set(PENUMBRA_PYTHON_MODULE ON)
  else()
    message(STATUS "penumbra: pybind11 or Python 3 development files not found; no Python module")
  endif()
endif()
