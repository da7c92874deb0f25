# Helpers shared by the tree and by out-of-tree plugins (installed with the package).

# simgate_add_transport_plugin(NAME [NO_INSTALL] SOURCES...)
#   Builds libsimgate_transport_<NAME>.so, a module the gateway loads with dlopen.
#   The sources must use SIMGATE_TRANSPORT_PLUGIN(<NAME>, Class) once. NO_INSTALL: a
#   test-only plugin, never installed.
function(simgate_add_transport_plugin name)
  cmake_parse_arguments(arg "NO_INSTALL" "" "" ${ARGN})
  _simgate_add_plugin_module(simgate_transport_${name} core "${arg_NO_INSTALL}" ${arg_UNPARSED_ARGUMENTS})
endfunction()

# simgate_add_component_library(NAME [NO_INSTALL] SOURCES...)
#   Builds libsimgate_components_<NAME>.so, a component library a config names in
#   "component_libraries" and the gateway loads with dlopen (sim/component_library.h). The
#   sources must use SIMGATE_COMPONENT_LIBRARY(<NAME>, ...) once. Installed beside the
#   transport plugins, where the installed gateway finds it by name. NO_INSTALL: test only.
function(simgate_add_component_library name)
  cmake_parse_arguments(arg "NO_INSTALL" "" "" ${ARGN})
  _simgate_add_plugin_module(simgate_components_${name} sim "${arg_NO_INSTALL}" ${arg_UNPARSED_ARGUMENTS})
endfunction()

# _simgate_add_plugin_module(TARGET LAYER NO_INSTALL SOURCES...)
#   What both kinds of plugin share: a MODULE linked to simgate's LAYER library (core or
#   sim: the tree's target, or the installed package's simgate::LAYER), hidden symbols, its
#   thread-locals in the static TLS block, built into the tree's plugin directory and
#   installed beside the gateway's plugins unless NO_INSTALL.
function(_simgate_add_plugin_module target layer no_install)
  add_library(${target} MODULE ${ARGN})
  if(TARGET simgate_${layer})
    target_link_libraries(${target} PRIVATE simgate_${layer})
  else()
    target_link_libraries(${target} PRIVATE simgate::${layer})
  endif()
  set_target_properties(${target} PROPERTIES
    CXX_VISIBILITY_PRESET hidden
    VISIBILITY_INLINES_HIDDEN ON)
  # the module's thread-local variables (Asio's call stack, read on every handler it
  # allocates) go in the static TLS block glibc keeps for dlopen: a plain %fs access instead
  # of a __tls_get_addr call, and no heap-allocated TLS block per thread (GCC 12's
  # LeakSanitizer misreads such a block at exit and crashes). Needs a few bytes of TLS only.
  target_compile_options(${target} PRIVATE -ftls-model=initial-exec)
  if(DEFINED SIMGATE_PLUGIN_BUILD_DIR)
    set_target_properties(${target} PROPERTIES LIBRARY_OUTPUT_DIRECTORY ${SIMGATE_PLUGIN_BUILD_DIR})
  endif()
  if(DEFINED SIMGATE_PLUGIN_INSTALL_DIR AND TARGET simgate_${layer} AND NOT no_install)
    # installed in <libdir>/simgate/plugins, it finds simgate's libraries in <libdir>: $ORIGIN/../..
    simgate_install_rpath(rpath ${SIMGATE_PLUGIN_INSTALL_DIR})
    set_target_properties(${target} PROPERTIES INSTALL_RPATH "${rpath}")
    install(TARGETS ${target} LIBRARY DESTINATION ${SIMGATE_PLUGIN_INSTALL_DIR})
  endif()
endfunction()

# simgate_install_rpath(VAR DIR)
#   Sets VAR to "$ORIGIN/<path from DIR to CMAKE_INSTALL_LIBDIR>" (both relative to the
#   install prefix): an installed file in DIR finds simgate's libraries wherever the prefix
#   is moved. Falls back to the absolute library directory when either is absolute.
function(simgate_install_rpath var dir)
  if(IS_ABSOLUTE "${dir}" OR IS_ABSOLUTE "${CMAKE_INSTALL_LIBDIR}")
    set(${var} "${CMAKE_INSTALL_FULL_LIBDIR}" PARENT_SCOPE)
    return()
  endif()
  file(RELATIVE_PATH rel "/simgate-prefix/${dir}" "/simgate-prefix/${CMAKE_INSTALL_LIBDIR}")
  string(REGEX REPLACE "/+$" "" rel "${rel}")
  if(rel STREQUAL "")
    set(${var} "$ORIGIN" PARENT_SCOPE)
  else()
    set(${var} "$ORIGIN/${rel}" PARENT_SCOPE)
  endif()
endfunction()

# simgate_add_test(NAME SOURCES... [LIBS libs...] [LABELS labels...] [TIMEOUT s])
#   A GoogleTest executable registered with CTest, test by test.
function(simgate_add_test name)
  cmake_parse_arguments(arg "" "TIMEOUT" "SOURCES;LIBS;LABELS;ENV" ${ARGN})
  find_package(GTest REQUIRED)
  include(GoogleTest)
  add_executable(${name} ${arg_SOURCES} ${arg_UNPARSED_ARGUMENTS})
  target_link_libraries(${name} PRIVATE GTest::gtest GTest::gtest_main GTest::gmock ${arg_LIBS})
  if(NOT arg_TIMEOUT)
    set(arg_TIMEOUT 120)
  endif()
  # where tests find the tree, the build and the plugins (never hard-coded paths)
  target_compile_definitions(${name} PRIVATE
    SIMGATE_SOURCE_DIR="${PROJECT_SOURCE_DIR}"
    SIMGATE_BINARY_DIR="${PROJECT_BINARY_DIR}"
    SIMGATE_TEST_PLUGIN_DIR="${SIMGATE_PLUGIN_BUILD_DIR}"
    SIMGATE_LOOPBACK_DDS_XML="${PROJECT_SOURCE_DIR}/config/dds/loopback.xml")
  # Cyclone stays on loopback in every test, even one that forgets to pass the XML
  set(properties TIMEOUT ${arg_TIMEOUT}
                 ENVIRONMENT "CYCLONEDDS_URI=file://${PROJECT_SOURCE_DIR}/config/dds/loopback.xml")
  if(arg_LABELS)
    list(APPEND properties LABELS "${arg_LABELS}")
  endif()
  gtest_discover_tests(${name} PROPERTIES ${properties} DISCOVERY_TIMEOUT 60)
endfunction()

# simgate_pypi_pythonpath(VAR REQUIREMENTS): sets VAR (unless already set, e.g. with -DVAR=DIR) to
# where scripts/test installs the packages pinned by REQUIREMENTS (a pypi-requirements.txt;
# scripts/lib.sh ensure_python_test_clients): the user's cache, in a directory named after
# the pins, named here the same way (a change of the file configures again).
function(simgate_pypi_pythonpath var requirements)
  if(${var})
    return()
  endif()
  set_property(DIRECTORY APPEND PROPERTY CMAKE_CONFIGURE_DEPENDS ${requirements})
  file(STRINGS ${requirements} pins REGEX "^[^#]")
  list(JOIN pins "_" pins)
  string(REPLACE "==" "-" pins "${pins}")
  if(DEFINED ENV{XDG_CACHE_HOME} AND NOT "$ENV{XDG_CACHE_HOME}" STREQUAL "")
    set(${var} "$ENV{XDG_CACHE_HOME}/simgate/python-${pins}" PARENT_SCOPE)
  else()
    set(${var} "$ENV{HOME}/.cache/simgate/python-${pins}" PARENT_SCOPE)
  endif()
endfunction()
