# Install and export rules: `cmake --install build --prefix P` puts the libraries, their headers
# and a package configuration under P, so that another project can find_package(uwbloc).
include(CMakePackageConfigHelpers)

set(UWBLOC_LIBRARIES uwbloc_uwb uwbloc_nlos uwbloc_localization uwbloc_dataset uwbloc_evaluation)
foreach(lib ${UWBLOC_LIBRARIES})
  string(REPLACE "uwbloc_" "" short ${lib})
  set_target_properties(${lib} PROPERTIES EXPORT_NAME ${short})
  add_library(uwbloc::${short} ALIAS ${lib})
endforeach()
install(TARGETS ${UWBLOC_LIBRARIES} EXPORT uwblocTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
        LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR})
foreach(dir uwb nlos localization dataset evaluation)
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/libs/${dir}/include/
          DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
endforeach()
# The bundled manifests and scenarios, where an installed uwbloc looks for them.
install(DIRECTORY ${PROJECT_SOURCE_DIR}/datasets/ DESTINATION ${CMAKE_INSTALL_DATADIR}/uwbloc/datasets)

set(config_dir ${CMAKE_INSTALL_LIBDIR}/cmake/uwbloc)
install(EXPORT uwblocTargets NAMESPACE uwbloc:: DESTINATION ${config_dir})
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/uwblocConfig.cmake.in
                              ${PROJECT_BINARY_DIR}/uwblocConfig.cmake
                              INSTALL_DESTINATION ${config_dir})
write_basic_package_version_file(${PROJECT_BINARY_DIR}/uwblocConfigVersion.cmake
                                 COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/uwblocConfig.cmake
              ${PROJECT_BINARY_DIR}/uwblocConfigVersion.cmake
        DESTINATION ${config_dir})
