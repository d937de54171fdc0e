# CMake package of the animcodec C library, installed by capi/install.sh as
# PREFIX/lib/cmake/animcodec/animcodecConfig.cmake. Consumers:
#   find_package(animcodec REQUIRED)            # with -DCMAKE_PREFIX_PATH=PREFIX
#   target_link_libraries(my_player PRIVATE animcodec::animcodec)
get_filename_component(_animcodec_prefix "${CMAKE_CURRENT_LIST_DIR}/../../.." ABSOLUTE)
if(NOT TARGET animcodec::animcodec)
  add_library(animcodec::animcodec SHARED IMPORTED)
  set_target_properties(animcodec::animcodec PROPERTIES
    IMPORTED_LOCATION "${_animcodec_prefix}/lib/libanimcodec_capi${CMAKE_SHARED_LIBRARY_SUFFIX}"
    INTERFACE_INCLUDE_DIRECTORIES "${_animcodec_prefix}/include")
endif()
if(NOT TARGET animcodec::animcodec_static)
  add_library(animcodec::animcodec_static STATIC IMPORTED)
  set_target_properties(animcodec::animcodec_static PROPERTIES
    IMPORTED_LOCATION "${_animcodec_prefix}/lib/libanimcodec_capi${CMAKE_STATIC_LIBRARY_SUFFIX}"
    INTERFACE_INCLUDE_DIRECTORIES "${_animcodec_prefix}/include"
    INTERFACE_LINK_LIBRARIES "pthread;dl;m")
endif()
unset(_animcodec_prefix)
