# Sanitizer and fuzzing builds (docs/reliability.md).
#
#   -DPENUMBRA_SANITIZE=address,undefined   any comma list of address, undefined, leak, thread
#                                           (ON means address,undefined; OFF or empty: none)
#   -DPENUMBRA_FUZZ=ON                      libFuzzer harnesses in fuzz/ (clang only); every library
#                                           is built with coverage instrumentation, and the
#                                           sanitizers default to address,undefined
#
# Undefined behaviour is fatal (-fno-sanitize-recover), so a test or fuzz run that triggers it
# fails instead of printing a line nobody reads.

set(PENUMBRA_SANITIZE "" CACHE STRING "sanitizers, a comma list such as address,undefined (ON: address,undefined)")
option(PENUMBRA_FUZZ "Build the libFuzzer harnesses in fuzz/ (clang only)" OFF)

set(_sanitizers "${PENUMBRA_SANITIZE}")
if(_sanitizers STREQUAL "ON" OR _sanitizers STREQUAL "TRUE" OR _sanitizers STREQUAL "1")
  set(_sanitizers "address,undefined")
elseif(_sanitizers STREQUAL "OFF" OR _sanitizers STREQUAL "FALSE" OR _sanitizers STREQUAL "0")
  set(_sanitizers "")
endif()
if(PENUMBRA_FUZZ)
  if(NOT CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
    message(FATAL_ERROR "PENUMBRA_FUZZ needs clang (libFuzzer): configure with -DCMAKE_CXX_COMPILER=clang++")
  endif()
  if(_sanitizers STREQUAL "")
    set(_sanitizers "address,undefined")
  endif()
endif()

if(NOT _sanitizers STREQUAL "")
  string(REPLACE "," ";" _list "${_sanitizers}")
  foreach(_s IN LISTS _list)
    if(NOT _s MATCHES "^(address|undefined|leak|thread)$")
      message(FATAL_ERROR "PENUMBRA_SANITIZE: unknown sanitizer '${_s}' (known: address, undefined, leak, thread)")
    endif()
  endforeach()
  if("address" IN_LIST _list AND "thread" IN_LIST _list)
    message(FATAL_ERROR "PENUMBRA_SANITIZE: address and thread cannot be combined")
  endif()
  add_compile_options(-fsanitize=${_sanitizers} -fno-omit-frame-pointer)
  add_link_options(-fsanitize=${_sanitizers})
  if("undefined" IN_LIST _list)
    add_compile_options(-fno-sanitize-recover=undefined)
    if(CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
      add_compile_options(-fsanitize-ignorelist=${CMAKE_CURRENT_LIST_DIR}/sanitize-ignore.txt)
    endif()
  endif()
  message(STATUS "penumbra: sanitizers ${_sanitizers}")
endif()
if(PENUMBRA_FUZZ)
  add_compile_options(-fsanitize=fuzzer-no-link)
endif()
