# Finds CHOLMOD (SuiteSparse) from Debian's libsuitesparse-dev, which ships no CMake
# config in version 5. Defines CHOLMOD::CHOLMOD.
find_path(CHOLMOD_INCLUDE_DIR cholmod.h PATH_SUFFIXES suitesparse)
find_library(CHOLMOD_LIBRARY cholmod)
find_library(SUITESPARSE_CONFIG_LIBRARY suitesparseconfig)
foreach(lib amd colamd camd ccolamd)
  string(TOUPPER ${lib} LIB)
  find_library(${LIB}_LIBRARY ${lib})
endforeach()
# CHOLMOD's BLAS (libcholmod links it; meshpde also calls dsyrk itself when it is found).
find_library(CHOLMOD_BLAS_LIBRARY NAMES blas openblas)
include(FindPackageHandleStandardArgs)
find_package_handle_standard_args(CHOLMOD REQUIRED_VARS CHOLMOD_LIBRARY CHOLMOD_INCLUDE_DIR SUITESPARSE_CONFIG_LIBRARY
                                  AMD_LIBRARY COLAMD_LIBRARY)
if(CHOLMOD_FOUND AND NOT TARGET CHOLMOD::CHOLMOD)
  add_library(CHOLMOD::CHOLMOD UNKNOWN IMPORTED)
  set_target_properties(CHOLMOD::CHOLMOD PROPERTIES
    IMPORTED_LOCATION "${CHOLMOD_LIBRARY}"
    INTERFACE_INCLUDE_DIRECTORIES "${CHOLMOD_INCLUDE_DIR}"
    INTERFACE_LINK_LIBRARIES "${AMD_LIBRARY};${COLAMD_LIBRARY};${CAMD_LIBRARY};${CCOLAMD_LIBRARY};${SUITESPARSE_CONFIG_LIBRARY}")
  if(CHOLMOD_BLAS_LIBRARY)
    set_property(TARGET CHOLMOD::CHOLMOD APPEND PROPERTY INTERFACE_LINK_LIBRARIES "${CHOLMOD_BLAS_LIBRARY}")
  endif()
endif()
mark_as_advanced(CHOLMOD_INCLUDE_DIR CHOLMOD_LIBRARY SUITESPARSE_CONFIG_LIBRARY AMD_LIBRARY COLAMD_LIBRARY CAMD_LIBRARY
                 CCOLAMD_LIBRARY CHOLMOD_BLAS_LIBRARY)
