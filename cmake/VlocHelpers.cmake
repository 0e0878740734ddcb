# vloc's build helpers: one function each for libraries, processes/tools,
# tests and benchmarks. Sources are always listed explicitly; flags are per
# target.

function(vloc_target_flags target)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wno-unused-parameter -Wno-missing-field-initializers)
  if(VLOC_WARNINGS_AS_ERRORS)
    target_compile_options(${target} PRIVATE -Werror)
  endif()
  if(VLOC_SANITIZE)
    target_compile_options(${target} PRIVATE -fsanitize=address,undefined -fno-omit-frame-pointer)
    target_link_options(${target} PRIVATE -fsanitize=address,undefined)
  endif()
endfunction()

# vloc_add_library(NAME SOURCES a.cpp ... DEPS target ...)
# Creates vloc_<NAME> with alias vloc::<NAME>; headers in include/ are public.
function(vloc_add_library name)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPS;PRIVATE_DEPS" ${ARGN})
  set(target vloc_${name})
  add_library(${target} STATIC ${ARG_SOURCES})
  add_library(vloc::${name} ALIAS ${target})
  target_include_directories(${target} PUBLIC ${CMAKE_CURRENT_SOURCE_DIR}/include)
  target_link_libraries(${target} PUBLIC ${ARG_DEPS} PRIVATE ${ARG_PRIVATE_DEPS})
  set_target_properties(${target} PROPERTIES POSITION_INDEPENDENT_CODE ON)
  vloc_target_flags(${target})
endfunction()

# vloc_add_proc(NAME SOURCES main.cpp ... DEPS target ...)
# An executable (process or command-line tool) placed in <build>/bin.
function(vloc_add_proc name)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE ${ARG_DEPS})
  set_target_properties(${name} PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${CMAKE_BINARY_DIR}/bin)
  vloc_target_flags(${name})
endfunction()

# vloc_test_command(OUT NAME COMMAND [ARGS...]): the command line that runs a
# test with a temporary folder of its own (TMPDIR), removed when it ends
# (tests/support/run_with_tmpdir.sh); every add_test goes through it.
function(vloc_test_command out name)
  set(${out} sh ${CMAKE_SOURCE_DIR}/tests/support/run_with_tmpdir.sh ${name} ${ARGN} PARENT_SCOPE)
endfunction()

# vloc_add_test(NAME SOURCES t.cpp ... DEPS target ... [LABELS l ...] [TIMEOUT s] [GTEST])
# A test executable registered with CTest. GTEST links gtest_main. The test
# runs from the source root so paths like config/x.yaml resolve, gets
# VLOC_BIN_DIR / VLOC_SOURCE_DIR in its environment and a TMPDIR of its own.
function(vloc_add_test name)
  cmake_parse_arguments(ARG "GTEST" "TIMEOUT" "SOURCES;DEPS;LABELS;ARGS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE ${ARG_DEPS})
  if(ARG_GTEST)
    target_link_libraries(${name} PRIVATE GTest::gtest GTest::gtest_main GTest::gmock)
  endif()
  set_target_properties(${name} PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${CMAKE_BINARY_DIR}/tests)
  target_compile_definitions(${name} PRIVATE
    VLOC_SOURCE_DIR="${CMAKE_SOURCE_DIR}" VLOC_BIN_DIR="${CMAKE_BINARY_DIR}/bin")
  vloc_target_flags(${name})
  vloc_test_command(command ${name} $<TARGET_FILE:${name}> ${ARG_ARGS})
  add_test(NAME ${name} COMMAND ${command} WORKING_DIRECTORY ${CMAKE_SOURCE_DIR})
  if(NOT ARG_TIMEOUT)
    set(ARG_TIMEOUT 300)
  endif()
  set_tests_properties(${name} PROPERTIES TIMEOUT ${ARG_TIMEOUT}
    ENVIRONMENT "VLOC_BIN_DIR=${CMAKE_BINARY_DIR}/bin;VLOC_SOURCE_DIR=${CMAKE_SOURCE_DIR};VLOC_BUILD_DIR=${CMAKE_BINARY_DIR}")
  # Every test carries the label of its folder under tests/ (unit, procs,
  # integration), so `ctest -L unit` runs every unit test; LABELS add more.
  file(RELATIVE_PATH rel ${CMAKE_SOURCE_DIR}/tests ${CMAKE_CURRENT_SOURCE_DIR})
  string(REGEX REPLACE "/.*" "" folder "${rel}")
  set(labels ${folder} ${ARG_LABELS})
  list(REMOVE_DUPLICATES labels)
  set_tests_properties(${name} PROPERTIES LABELS "${labels}")
endfunction()

# vloc_add_benchmark(NAME SOURCES b.cpp ... DEPS target ...)
# A Google Benchmark program in <build>/bench (not run by ctest).
function(vloc_add_benchmark name)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPS" ${ARGN})
  if(NOT VLOC_BUILD_BENCHMARKS)
    return()
  endif()
  add_executable(${name} ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE ${ARG_DEPS} benchmark::benchmark)
  set_target_properties(${name} PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${CMAKE_BINARY_DIR}/bench)
  target_compile_definitions(${name} PRIVATE VLOC_SOURCE_DIR="${CMAKE_SOURCE_DIR}")
  vloc_target_flags(${name})
endfunction()

# Adds each listed subdirectory; a listed folder without a CMakeLists.txt
# is an error (a silent skip would drop its tests from CI unnoticed).
# VLOC_ONLY_DIRS (cache, optional): when set, only these folder names are
# added - for building one part of the tree while others are mid-change.
function(vloc_add_subdirectories)
  foreach(dir ${ARGN})
    if(VLOC_ONLY_DIRS AND NOT dir IN_LIST VLOC_ONLY_DIRS)
      continue()
    endif()
    if(NOT EXISTS ${CMAKE_CURRENT_SOURCE_DIR}/${dir}/CMakeLists.txt)
      message(FATAL_ERROR "${CMAKE_CURRENT_SOURCE_DIR}/${dir}/CMakeLists.txt is missing: "
                          "add it or take '${dir}' out of the list in ${CMAKE_CURRENT_LIST_FILE}")
    endif()
    add_subdirectory(${dir})
  endforeach()
endfunction()
