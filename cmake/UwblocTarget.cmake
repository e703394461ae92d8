# One place that sets the language standard and warnings on every project target.
function(uwbloc_configure_target target)
  target_compile_features(${target} PUBLIC cxx_std_17)
  set_target_properties(${target} PROPERTIES CXX_EXTENSIONS OFF)
  if(CMAKE_CXX_COMPILER_ID MATCHES "GNU|Clang")
    target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic -Wno-deprecated-copy)
  endif()
endfunction()

# One project library: its sources, its public headers under include/ (installed as they are),
# the standard and warnings. Dependencies are linked by the caller.
function(uwbloc_library target)
  add_library(${target} ${ARGN})
  target_include_directories(${target} PUBLIC $<BUILD_INTERFACE:${CMAKE_CURRENT_SOURCE_DIR}/include>
                                              $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>)
  uwbloc_configure_target(${target})
endfunction()
