# CMake package of orbitflex's C API. Install it as <prefix>/lib/cmake/orbitflex/ beside
# <prefix>/lib/liborbitflex_c.{so,a} and <prefix>/include/orbitflex.h, then:
#   find_package(orbitflex CONFIG REQUIRED)            # -DCMAKE_PREFIX_PATH=<prefix>
#   target_link_libraries(app PRIVATE orbitflex::orbitflex)          # shared
#   target_link_libraries(app PRIVATE orbitflex::orbitflex_static)   # static
get_filename_component(_orbitflex_prefix "${CMAKE_CURRENT_LIST_DIR}/../../.." ABSOLUTE)
if(NOT TARGET orbitflex::orbitflex)
  add_library(orbitflex::orbitflex SHARED IMPORTED)
  set_target_properties(orbitflex::orbitflex PROPERTIES
    IMPORTED_LOCATION "${_orbitflex_prefix}/lib/liborbitflex_c.so"
    INTERFACE_INCLUDE_DIRECTORIES "${_orbitflex_prefix}/include")
endif()
if(NOT TARGET orbitflex::orbitflex_static AND EXISTS "${_orbitflex_prefix}/lib/liborbitflex_c.a")
  add_library(orbitflex::orbitflex_static STATIC IMPORTED)
  set_target_properties(orbitflex::orbitflex_static PROPERTIES
    IMPORTED_LOCATION "${_orbitflex_prefix}/lib/liborbitflex_c.a"
    INTERFACE_INCLUDE_DIRECTORIES "${_orbitflex_prefix}/include"
    INTERFACE_LINK_LIBRARIES "gcc_s;util;rt;pthread;m;dl")
endif()
unset(_orbitflex_prefix)
