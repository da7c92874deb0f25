# simgate_find_mujoco()
#   Defines the imported target simgate::mujoco (MuJoCo's library and headers) unless it
#   exists, and sets
#     SIMGATE_MUJOCO_FOUND     TRUE or FALSE
#     SIMGATE_MUJOCO_VERSION   "4.0.0", read from mujoco.h's mjVERSION_HEADER
#     MUJOCO_LIBRARY, MUJOCO_INCLUDE_DIR   the files found (cache variables)
#   Where MuJoCo is found: MUJOCO_LIBRARY and MUJOCO_INCLUDE_DIR, when both are set (the
#   files themselves: the installed simgateConfig.cmake names the copy it carries); else
#   MUJOCO_DIR (CMake or environment variable): a MuJoCo whose headers are under
#   include/mujoco/ and whose library libmujoco.so* is in it or in its lib/ — the PyPI
#   wheel's mujoco/ directory (scripts/lib.sh's ensure_mujoco installs the pinned one, which
#   sim/CMakeLists.txt names unless the user names another), or a user's own build or
#   install. The system is not searched (Debian 12's libmujoco-dev is 2.2.2, which simgate
#   no longer builds on).
#   Used by the tree (sim/) and by the installed simgateConfig.cmake.
macro(simgate_find_mujoco)
  if(NOT TARGET simgate::mujoco)
    if(NOT DEFINED MUJOCO_DIR AND DEFINED ENV{MUJOCO_DIR})
      set(MUJOCO_DIR "$ENV{MUJOCO_DIR}")
    endif()
    # MUJOCO_DIR changed since the last configure: what was found before is forgotten
    if(DEFINED SIMGATE_MUJOCO_SEARCHED_DIR AND NOT "${SIMGATE_MUJOCO_SEARCHED_DIR}" STREQUAL "${MUJOCO_DIR}")
      unset(MUJOCO_LIBRARY CACHE)
      unset(MUJOCO_INCLUDE_DIR CACHE)
    endif()
    set(SIMGATE_MUJOCO_SEARCHED_DIR "${MUJOCO_DIR}" CACHE INTERNAL "the MUJOCO_DIR of the last search")
    if(MUJOCO_LIBRARY AND MUJOCO_INCLUDE_DIR)
      # named by the user, or by the installed simgateConfig.cmake (the MuJoCo it carries)
    elseif(MUJOCO_DIR)
      # the wheel carries only libmujoco.so.X.Y.Z (its SONAME), no libmujoco.so link
      file(GLOB _simgate_mujoco_libs "${MUJOCO_DIR}/libmujoco.so*" "${MUJOCO_DIR}/lib/libmujoco.so*")
      list(SORT _simgate_mujoco_libs)     # libmujoco.so, if present, sorts first
      if(NOT MUJOCO_LIBRARY AND _simgate_mujoco_libs)
        list(GET _simgate_mujoco_libs 0 _simgate_mujoco_lib)
        set(MUJOCO_LIBRARY "${_simgate_mujoco_lib}" CACHE FILEPATH "MuJoCo's library" FORCE)
      endif()
      find_path(MUJOCO_INCLUDE_DIR mujoco/mujoco.h PATHS "${MUJOCO_DIR}/include" NO_DEFAULT_PATH)
      unset(_simgate_mujoco_libs)
      unset(_simgate_mujoco_lib)
    endif()
    if(MUJOCO_LIBRARY AND MUJOCO_INCLUDE_DIR)
      # SHARED (not UNKNOWN): CMake then puts the library's directory in the build tree's
      # RPATH, so that binaries built against the wheel find it there
      add_library(simgate::mujoco SHARED IMPORTED)
      set_target_properties(simgate::mujoco PROPERTIES
        IMPORTED_LOCATION "${MUJOCO_LIBRARY}"
        INTERFACE_INCLUDE_DIRECTORIES "${MUJOCO_INCLUDE_DIR}")
      # mjVERSION_HEADER: 222 for 2.2.2, then major * 1000000 + minor * 1000 + patch
      file(STRINGS "${MUJOCO_INCLUDE_DIR}/mujoco/mujoco.h" _simgate_mujoco_line
        REGEX "^#define mjVERSION_HEADER [0-9]+")
      string(REGEX REPLACE ".* ([0-9]+).*" "\\1" _simgate_mujoco_v "${_simgate_mujoco_line}")
      if(_simgate_mujoco_v GREATER_EQUAL 1000000)
        math(EXPR _simgate_mujoco_major "${_simgate_mujoco_v} / 1000000")
        math(EXPR _simgate_mujoco_minor "${_simgate_mujoco_v} / 1000 % 1000")
        math(EXPR _simgate_mujoco_patch "${_simgate_mujoco_v} % 1000")
        set(SIMGATE_MUJOCO_VERSION "${_simgate_mujoco_major}.${_simgate_mujoco_minor}.${_simgate_mujoco_patch}")
      else()
        string(REGEX REPLACE "(.)(.)(.)" "\\1.\\2.\\3" SIMGATE_MUJOCO_VERSION "${_simgate_mujoco_v}")
      endif()
      set_target_properties(simgate::mujoco PROPERTIES VERSION "${SIMGATE_MUJOCO_VERSION}")
      foreach(_simgate_mujoco_var line v major minor patch)
        unset(_simgate_mujoco_${_simgate_mujoco_var})
      endforeach()
    endif()
  endif()
  if(TARGET simgate::mujoco)
    set(SIMGATE_MUJOCO_FOUND TRUE)
    get_target_property(SIMGATE_MUJOCO_VERSION simgate::mujoco VERSION)
  else()
    set(SIMGATE_MUJOCO_FOUND FALSE)
  endif()
endmacro()
