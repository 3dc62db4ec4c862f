# PfunitLite.cmake: a small fallback for pFUnit 4, used when find_package(PFUNIT 4) fails.
#
#   include(PfunitLite)
#   add_pfunit_ctest(<name> TEST_SOURCES <a.pf>... [OTHER_SOURCES <f90>...]
#                    [LINK_LIBRARIES <targets>...] [MAX_PES <n>] [LABELS <l>...]
#                    [WILL_FAIL] [NO_TEST])
#
# builds the executable <name> from the .pf files (translated at build time by
# tests/pfunit_lite/pfproc.py, which rejects what pFUnit 4.14 would reject) and registers the
# CTest test <name>. As with pFUnit: with MAX_PES it runs under
# `mpiexec ${MPIEXEC_PREFLAGS} -n <MAX_PES>`, without it the target is serial (no `pfunit`
# module, no MPI tests) and runs without mpiexec; no compile options are added (pass
# -ffree-line-length-none yourself, as pFUnit's targets need it too). WILL_FAIL and NO_TEST
# (not in pFUnit: the test must fail; no test is registered) are for the fallback's
# self-tests only.
# See tests/pfunit_lite/README.md. Including this file twice is harmless.

find_package(Python3 COMPONENTS Interpreter REQUIRED)
find_package(MPI REQUIRED COMPONENTS Fortran)
set(PFUNIT_LITE TRUE)

if(NOT TARGET pfunit_lite)
  set(_pfl_src "${CMAKE_CURRENT_LIST_DIR}/../tests/pfunit_lite")
  add_library(pfunit_lite STATIC "${_pfl_src}/funit.F90" "${_pfl_src}/pfunit.F90")
  set_target_properties(pfunit_lite PROPERTIES
    Fortran_MODULE_DIRECTORY "${CMAKE_CURRENT_BINARY_DIR}/pfunit_lite_modules")
  target_include_directories(pfunit_lite PUBLIC "${CMAKE_CURRENT_BINARY_DIR}/pfunit_lite_modules")
  target_link_libraries(pfunit_lite PUBLIC MPI::MPI_Fortran)
  unset(_pfl_src)
endif()

function(add_pfunit_ctest name)
  cmake_parse_arguments(PARSE_ARGV 1 arg "WILL_FAIL;NO_TEST" "MAX_PES"
                        "TEST_SOURCES;OTHER_SOURCES;LINK_LIBRARIES;LABELS")
  if(NOT arg_TEST_SOURCES)
    message(FATAL_ERROR "add_pfunit_ctest(${name}): TEST_SOURCES is required")
  endif()
  if(arg_UNPARSED_ARGUMENTS)
    message(FATAL_ERROR "add_pfunit_ctest(${name}): unknown arguments ${arg_UNPARSED_ARGUMENTS}")
  endif()
  set(serial)
  if(NOT arg_MAX_PES)
    set(serial --serial)     # pFUnit links such a target with funit only
  endif()
  set(script "${CMAKE_CURRENT_FUNCTION_LIST_DIR}/../tests/pfunit_lite/pfproc.py")
  set(gen "${CMAKE_CURRENT_BINARY_DIR}/${name}_pfunit_lite")

  # one generated .F90 per .pf, and the driver that runs them in the order given
  set(pf_files)
  set(f90_files)
  foreach(pf IN LISTS arg_TEST_SOURCES)
    get_filename_component(pf "${pf}" ABSOLUTE)
    get_filename_component(stem "${pf}" NAME_WE)
    add_custom_command(
      OUTPUT "${gen}/${stem}.F90"
      COMMAND "${Python3_EXECUTABLE}" "${script}" ${serial} "${pf}" "${gen}/${stem}.F90"
      DEPENDS "${pf}" "${script}"
      COMMENT "pfunit_lite: preprocessing ${stem}.pf"
      VERBATIM)
    list(APPEND pf_files "${pf}")
    list(APPEND f90_files "${gen}/${stem}.F90")
  endforeach()
  add_custom_command(
    OUTPUT "${gen}/${name}_driver.F90"
    COMMAND "${Python3_EXECUTABLE}" "${script}" --driver ${serial}
            "${gen}/${name}_driver.F90" ${pf_files}
    DEPENDS ${pf_files} "${script}"
    COMMENT "pfunit_lite: writing the driver of ${name}"
    VERBATIM)

  add_executable(${name} ${f90_files} "${gen}/${name}_driver.F90" ${arg_OTHER_SOURCES})
  set_target_properties(${name} PROPERTIES Fortran_MODULE_DIRECTORY "${gen}/modules")
  target_link_libraries(${name} PRIVATE pfunit_lite ${arg_LINK_LIBRARIES})

  if(arg_NO_TEST)
    return()
  endif()
  if(serial)
    add_test(NAME ${name} COMMAND $<TARGET_FILE:${name}>)
    set(npes 1)
  else()
    add_test(NAME ${name}
      COMMAND "${MPIEXEC_EXECUTABLE}" ${MPIEXEC_PREFLAGS} ${MPIEXEC_NUMPROC_FLAG} ${arg_MAX_PES}
              $<TARGET_FILE:${name}> ${MPIEXEC_POSTFLAGS})
    set(npes ${arg_MAX_PES})
  endif()
  set_tests_properties(${name} PROPERTIES
    ENVIRONMENT "OMPI_ALLOW_RUN_AS_ROOT=1;OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1"
    TIMEOUT 300
    PROCESSORS ${npes})
  if(arg_LABELS)
    set_tests_properties(${name} PROPERTIES LABELS "${arg_LABELS}")
  endif()
  if(arg_WILL_FAIL)
    set_tests_properties(${name} PROPERTIES WILL_FAIL TRUE)
  endif()
endfunction()
