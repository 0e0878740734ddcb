# vloc_lcm_types(TARGET <name> JAR <jar name> FILES a.lcm ...)
# Runs lcm-gen for C++ (header-only INTERFACE target <name>) and for Java
# (compiled and packed into <jar name> in the build tree, for lcm-spy).
function(vloc_lcm_types)
  cmake_parse_arguments(ARG "" "TARGET;JAR" "FILES" ${ARGN})
  set(cpp_dir ${CMAKE_CURRENT_BINARY_DIR}/cpp)
  set(java_dir ${CMAKE_CURRENT_BINARY_DIR}/java)
  set(headers)
  set(java_sources)
  set(lcm_files)
  foreach(f ${ARG_FILES})
    get_filename_component(stem ${f} NAME_WE)
    list(APPEND headers ${cpp_dir}/vloc/${stem}.hpp)
    list(APPEND java_sources ${java_dir}/vloc/${stem}.java)
    list(APPEND lcm_files ${CMAKE_CURRENT_SOURCE_DIR}/${f})
  endforeach()
  add_custom_command(OUTPUT ${headers}
    COMMAND ${LCM_GEN} --cpp --cpp-hpath ${cpp_dir} ${lcm_files}
    DEPENDS ${lcm_files}
    COMMENT "lcm-gen C++ for vloc types")
  add_custom_target(${ARG_TARGET}_gen DEPENDS ${headers})
  add_library(${ARG_TARGET} INTERFACE)
  add_library(vloc::${ARG_TARGET} ALIAS ${ARG_TARGET})
  add_dependencies(${ARG_TARGET} ${ARG_TARGET}_gen)
  target_include_directories(${ARG_TARGET} INTERFACE ${cpp_dir})
  target_link_libraries(${ARG_TARGET} INTERFACE PkgConfig::LCM)

  if(Java_FOUND)
    include(UseJava)
    set(jar_path ${CMAKE_BINARY_DIR}/${ARG_JAR})
    set(class_dir ${CMAKE_CURRENT_BINARY_DIR}/java_classes)
    add_custom_command(OUTPUT ${jar_path}
      COMMAND ${CMAKE_COMMAND} -E make_directory ${java_dir} ${class_dir}
      COMMAND ${LCM_GEN} --java --jpath ${java_dir} ${lcm_files}
      COMMAND ${Java_JAVAC_EXECUTABLE} -nowarn -source 11 -target 11 -cp ${LCM_JAR} -d ${class_dir} ${java_sources}
      COMMAND ${Java_JAR_EXECUTABLE} cf ${jar_path} -C ${class_dir} .
      DEPENDS ${lcm_files}
      COMMENT "lcm-gen Java for vloc types -> ${ARG_JAR}")
    add_custom_target(${ARG_TARGET}_jar ALL DEPENDS ${jar_path})
  else()
    message(WARNING "No JDK found: ${ARG_JAR} (for lcm-spy) will not be built")
  endif()
endfunction()
