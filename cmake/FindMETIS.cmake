# FindMETIS: locate METIS 5 and read the integer and real widths from metis.h.
# Defines METIS::METIS, METIS_FOUND, METIS_INCLUDE_DIR, METIS_LIBRARY,
# METIS_IDX_WIDTH (32 or 64) and METIS_REAL_WIDTH (32 or 64).
find_path(METIS_INCLUDE_DIR metis.h PATH_SUFFIXES metis include)
find_library(METIS_LIBRARY NAMES metis)

if(METIS_INCLUDE_DIR AND EXISTS "${METIS_INCLUDE_DIR}/metis.h")
  file(STRINGS "${METIS_INCLUDE_DIR}/metis.h" _idx REGEX "^#define[ \t]+IDXTYPEWIDTH[ \t]+[0-9]+")
  file(STRINGS "${METIS_INCLUDE_DIR}/metis.h" _real REGEX "^#define[ \t]+REALTYPEWIDTH[ \t]+[0-9]+")
  string(REGEX REPLACE ".*IDXTYPEWIDTH[ \t]+([0-9]+).*" "\\1" METIS_IDX_WIDTH "${_idx}")
  string(REGEX REPLACE ".*REALTYPEWIDTH[ \t]+([0-9]+).*" "\\1" METIS_REAL_WIDTH "${_real}")
  file(STRINGS "${METIS_INCLUDE_DIR}/metis.h" _ver REGEX "^#define[ \t]+METIS_VER_(MAJOR|MINOR)")
  string(REGEX REPLACE ".*METIS_VER_MAJOR[ \t]+([0-9]+).*" "\\1" METIS_VERSION_MAJOR "${_ver}")
endif()

include(FindPackageHandleStandardArgs)
find_package_handle_standard_args(METIS
  REQUIRED_VARS METIS_LIBRARY METIS_INCLUDE_DIR METIS_IDX_WIDTH METIS_REAL_WIDTH)

if(METIS_FOUND AND NOT TARGET METIS::METIS)
  add_library(METIS::METIS UNKNOWN IMPORTED)
  set_target_properties(METIS::METIS PROPERTIES
    IMPORTED_LOCATION "${METIS_LIBRARY}"
    INTERFACE_INCLUDE_DIRECTORIES "${METIS_INCLUDE_DIR}")
  message(STATUS "METIS: idx_t ${METIS_IDX_WIDTH} bit, real_t ${METIS_REAL_WIDTH} bit")
endif()
mark_as_advanced(METIS_INCLUDE_DIR METIS_LIBRARY)
