# PfunitLite.cmake: a small fallback for pFUnit 4, used when find_package(PFUNIT 4) fails.
#
#   include(PfunitLite)
#   add_pfunit_ctest(<name> TEST_SOURCES <a.pf>... [OTHER_SOURCES <f90>...]
#                    [LINK_LIBRARIES <targets>...] [MAX_PES <n>] [LABELS <l>...] [WILL_FAIL])
#
# builds the executable <name> from the .pf files (translated at build time by
# tests/pfunit_lite/pfproc.py) and registers the CTest test <name>, run with
# MAX_PES ranks (default 1) under mpiexec. WILL_FAIL (not in pFUnit) marks a test that
# must fail; only the self-tests of the fallback use it. See tests/pfunit_lite/README.md.
# Including this file twice is harmless.

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

# Open MPI refuses more ranks than cores unless told; look once at configure time.
if(NOT DEFINED CACHE{PFUNIT_LITE_OVERSUBSCRIBE})
  execute_process(COMMAND "${MPIEXEC_EXECUTABLE}" --version
                  OUTPUT_VARIABLE _pfl_version ERROR_VARIABLE _pfl_version)
  set(_pfl_flag "")
  if(_pfl_version MATCHES "Open MPI|OpenRTE|open-mpi")
    set(_pfl_flag --oversubscribe)
  endif()
  set(PFUNIT_LITE_OVERSUBSCRIBE "${_pfl_flag}" CACHE INTERNAL "extra mpiexec flag of pfunit_lite")
  unset(_pfl_flag)
  unset(_pfl_version)
endif()

function(add_pfunit_ctest name)
  cmake_parse_arguments(PARSE_ARGV 1 arg "WILL_FAIL" "MAX_PES"
                        "TEST_SOURCES;OTHER_SOURCES;LINK_LIBRARIES;LABELS")
  if(NOT arg_TEST_SOURCES)
    message(FATAL_ERROR "add_pfunit_ctest(${name}): TEST_SOURCES is required")
  endif()
  if(arg_UNPARSED_ARGUMENTS)
    message(FATAL_ERROR "add_pfunit_ctest(${name}): unknown arguments ${arg_UNPARSED_ARGUMENTS}")
  endif()
  if(NOT arg_MAX_PES)
    set(arg_MAX_PES 1)
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
      COMMAND "${Python3_EXECUTABLE}" "${script}" "${pf}" "${gen}/${stem}.F90"
      DEPENDS "${pf}" "${script}"
      COMMENT "pfunit_lite: preprocessing ${stem}.pf"
      VERBATIM)
    list(APPEND pf_files "${pf}")
    list(APPEND f90_files "${gen}/${stem}.F90")
  endforeach()
  add_custom_command(
    OUTPUT "${gen}/${name}_driver.F90"
    COMMAND "${Python3_EXECUTABLE}" "${script}" --driver "${gen}/${name}_driver.F90" ${pf_files}
    DEPENDS ${pf_files} "${script}"
    COMMENT "pfunit_lite: writing the driver of ${name}"
    VERBATIM)

  add_executable(${name} ${f90_files} "${gen}/${name}_driver.F90" ${arg_OTHER_SOURCES})
  set_target_properties(${name} PROPERTIES Fortran_MODULE_DIRECTORY "${gen}/modules")
  # expanded assertions make long lines, as with pFUnit itself
  target_compile_options(${name} PRIVATE
    $<$<COMPILE_LANG_AND_ID:Fortran,GNU>:-ffree-line-length-none>)
  target_link_libraries(${name} PRIVATE pfunit_lite ${arg_LINK_LIBRARIES})

  add_test(NAME ${name}
    COMMAND "${MPIEXEC_EXECUTABLE}" ${MPIEXEC_NUMPROC_FLAG} ${arg_MAX_PES}
            ${MPIEXEC_PREFLAGS} ${PFUNIT_LITE_OVERSUBSCRIBE} $<TARGET_FILE:${name}> ${MPIEXEC_POSTFLAGS})
  set_tests_properties(${name} PROPERTIES
    ENVIRONMENT "OMPI_ALLOW_RUN_AS_ROOT=1;OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1"
    TIMEOUT 300
    PROCESSORS ${arg_MAX_PES})
  if(arg_LABELS)
    set_tests_properties(${name} PROPERTIES LABELS "${arg_LABELS}")
  endif()
  if(arg_WILL_FAIL)
    set_tests_properties(${name} PROPERTIES WILL_FAIL TRUE)
  endif()
endfunction()
