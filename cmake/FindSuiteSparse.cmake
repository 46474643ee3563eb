# FindSuiteSparse: Debian 12's SuiteSparse 5.12 ships no CMake config.
# Provides SuiteSparse::CHOLMOD, SuiteSparse::UMFPACK (and the include dir
# /usr/include/suitesparse that Eigen's CholmodSupport/UmfPackSupport need).
find_path(SuiteSparse_INCLUDE_DIR cholmod.h PATH_SUFFIXES suitesparse)
find_library(SuiteSparse_CHOLMOD_LIBRARY cholmod)
find_library(SuiteSparse_UMFPACK_LIBRARY umfpack)
find_library(SuiteSparse_AMD_LIBRARY amd)
find_library(SuiteSparse_COLAMD_LIBRARY colamd)
find_library(SuiteSparse_CONFIG_LIBRARY suitesparseconfig)

include(FindPackageHandleStandardArgs)
find_package_handle_standard_args(SuiteSparse
  REQUIRED_VARS SuiteSparse_INCLUDE_DIR SuiteSparse_CHOLMOD_LIBRARY
                SuiteSparse_UMFPACK_LIBRARY SuiteSparse_AMD_LIBRARY
                SuiteSparse_CONFIG_LIBRARY)

if(SuiteSparse_FOUND AND NOT TARGET SuiteSparse::CHOLMOD)
  add_library(SuiteSparse::config UNKNOWN IMPORTED)
  set_target_properties(SuiteSparse::config PROPERTIES
    IMPORTED_LOCATION "${SuiteSparse_CONFIG_LIBRARY}"
    INTERFACE_INCLUDE_DIRECTORIES "${SuiteSparse_INCLUDE_DIR}")
  add_library(SuiteSparse::AMD UNKNOWN IMPORTED)
  set_target_properties(SuiteSparse::AMD PROPERTIES
    IMPORTED_LOCATION "${SuiteSparse_AMD_LIBRARY}"
    INTERFACE_LINK_LIBRARIES SuiteSparse::config)
  add_library(SuiteSparse::CHOLMOD UNKNOWN IMPORTED)
  set_target_properties(SuiteSparse::CHOLMOD PROPERTIES
    IMPORTED_LOCATION "${SuiteSparse_CHOLMOD_LIBRARY}"
    INTERFACE_LINK_LIBRARIES "SuiteSparse::AMD;SuiteSparse::config")
  add_library(SuiteSparse::UMFPACK UNKNOWN IMPORTED)
  set_target_properties(SuiteSparse::UMFPACK PROPERTIES
    IMPORTED_LOCATION "${SuiteSparse_UMFPACK_LIBRARY}"
    INTERFACE_LINK_LIBRARIES "SuiteSparse::CHOLMOD;SuiteSparse::AMD;SuiteSparse::config")
endif()
mark_as_advanced(SuiteSparse_INCLUDE_DIR SuiteSparse_CHOLMOD_LIBRARY
  SuiteSparse_UMFPACK_LIBRARY SuiteSparse_AMD_LIBRARY SuiteSparse_COLAMD_LIBRARY
  SuiteSparse_CONFIG_LIBRARY)
