# One static library per source folder ("layer"), linked explicitly to the folders it builds
# on. A folder may include headers of itself and of the folders it links (transitively), and
# nothing else: every layer's files are checked at build time (cmake/check_layer.cmake), so an
# include that climbs a floor fails the build with the file, the include and what is allowed.
#
#   ii_add_layer(<folder> [DEPS <folders>...] [LIBS <libraries>...] [PCH])
#
# creates the target ii_<folder> from src/<folder>/*.cpp and src/<folder>/*/*.cpp. PCH: the
# folder uses LibTorch and shares the precompiled LibTorch header of the first such layer.
set(II_LAYER_SCRIPT ${CMAKE_CURRENT_LIST_DIR}/check_layer.cmake)

# A translation unit pays seconds before any code of ours (LibTorch's precompiled header, 375 MB;
# OpenCV's, Eigen's and the standard library's templates instantiated again in each file): every
# folder's files compile in batches, one translation unit per batch (a unity build;
# docs/benchmarks.md, "CI on a fresh machine": two batches of 8 LibTorch test files took 32 s,
# one of 16 took 22). Files with options of their own (the kernels compiled for an instruction
# set) stay alone. Off for a quicker rebuild of one file.
option(INSTAINPAINT_UNITY_BUILD "Compile each folder's files in batches" ON)
set(INSTAINPAINT_UNITY_BATCH_SIZE 32 CACHE STRING "Files per batch of a unity build")

#   ii_torch_target(<target>): the shared precompiled LibTorch header, and the batches.
function(ii_torch_target target)
  get_property(pch_owner GLOBAL PROPERTY II_PCH_OWNER)
  if(pch_owner)
    target_precompile_headers(${target} REUSE_FROM ${pch_owner})
  else()
    target_precompile_headers(${target} PUBLIC ${PROJECT_SOURCE_DIR}/src/common/torch.h)
    set_property(GLOBAL PROPERTY II_PCH_OWNER ${target})
  endif()
  ii_unity(${target})
endfunction()

#   ii_unity(<target>): the target's files in batches.
function(ii_unity target)
  if(NOT INSTAINPAINT_UNITY_BUILD)
    return()
  endif()
  if(CMAKE_VERSION VERSION_LESS 3.19)  # no deferred calls: CMake's own batches
    set_target_properties(${target} PROPERTIES UNITY_BUILD ON UNITY_BUILD_BATCH_SIZE ${INSTAINPAINT_UNITY_BATCH_SIZE})
  else()
    # At the end of the configuration, when every file's own options are known.
    # (EVAL: a deferred call's arguments are otherwise read when it runs, not now.)
    cmake_language(EVAL CODE "cmake_language(DEFER DIRECTORY [[${PROJECT_SOURCE_DIR}]] CALL ii_unity_batches [[${target}]])")
  endif()
endfunction()

# The batches are written here rather than by CMake's UNITY_BUILD, whose batch files include
# each source by its absolute path: a clone in another folder (CI's) compiled other text and
# missed every compiler-cache entry of the first. These include each source relative to the
# checkout, which is on the batch's include path, a path that ccache's CCACHE_BASEDIR makes
# relative: every clone compiles the same text. A batch is rewritten only when its files change.
function(ii_unity_batches target)
  get_target_property(sources ${target} SOURCES)
  get_target_property(dir ${target} SOURCE_DIR)
  # The C++ files without options of their own (CMake's unity build leaves those alone too).
  set(batched)
  foreach(source ${sources})
    get_filename_component(path ${source} ABSOLUTE BASE_DIR ${dir})
    if(NOT path MATCHES "\\.cpp$")
      continue()
    endif()
    set(alone OFF)
    foreach(property COMPILE_OPTIONS COMPILE_DEFINITIONS COMPILE_FLAGS INCLUDE_DIRECTORIES SKIP_UNITY_BUILD_INCLUSION)
      get_source_file_property(value ${path} DIRECTORY ${dir} ${property})
      if(value)
        set(alone ON)
      endif()
    endforeach()
    if(NOT alone)
      list(APPEND batched ${path})
    endif()
  endforeach()
  if(NOT batched)
    return()
  endif()
  # Then in batches of INSTAINPAINT_UNITY_BATCH_SIZE, each a file of #includes.
  list(LENGTH batched count)
  set(start 0)
  set(index 0)
  while(start LESS count)
    list(SUBLIST batched ${start} ${INSTAINPAINT_UNITY_BATCH_SIZE} batch_sources)
    set(text "// ${target}'s batch ${index} (cmake/layers.cmake)\n")
    foreach(path ${batch_sources})
      file(RELATIVE_PATH relative ${PROJECT_SOURCE_DIR} ${path})
      string(APPEND text "#include \"${relative}\"\n")
    endforeach()
    set(batch ${CMAKE_BINARY_DIR}/unity/${target}_${index}.cpp)
    file(CONFIGURE OUTPUT ${batch} CONTENT "${text}" @ONLY)
    target_sources(${target} PRIVATE ${batch})
    set_source_files_properties(${batch} DIRECTORY ${dir} PROPERTIES INCLUDE_DIRECTORIES ${PROJECT_SOURCE_DIR})
    math(EXPR start "${start} + ${INSTAINPAINT_UNITY_BATCH_SIZE}")
    math(EXPR index "${index} + 1")
  endwhile()
  set_source_files_properties(${batched} DIRECTORY ${dir} PROPERTIES HEADER_FILE_ONLY ON)
endfunction()

function(ii_add_layer folder)
  cmake_parse_arguments(L "PCH" "" "DEPS;LIBS" ${ARGN})
  set(dir ${PROJECT_SOURCE_DIR}/src/${folder})
  file(GLOB sources CONFIGURE_DEPENDS ${dir}/*.cpp ${dir}/*/*.cpp)
  file(GLOB files CONFIGURE_DEPENDS ${dir}/*.cpp ${dir}/*.h ${dir}/*/*.cpp ${dir}/*/*.h ${dir}/*/*.cu)
  set(target ii_${folder})
  if(sources)
    add_library(${target} STATIC ${sources})
    set(scope PUBLIC)
  else()
    add_library(${target} INTERFACE)  # headers only
    set(scope INTERFACE)
  endif()
  target_include_directories(${target} ${scope} ${PROJECT_SOURCE_DIR}/src)
  set(allowed ${folder})
  foreach(dep ${L_DEPS})
    target_link_libraries(${target} ${scope} ii_${dep})
    get_property(dep_allowed GLOBAL PROPERTY II_LAYER_${dep})
    list(APPEND allowed ${dep_allowed})
  endforeach()
  if(L_LIBS)
    target_link_libraries(${target} ${scope} ${L_LIBS})
  endif()
  list(REMOVE_DUPLICATES allowed)
  set_property(GLOBAL PROPERTY II_LAYER_${folder} ${allowed})
  if(L_PCH AND sources)
    ii_torch_target(${target})
  elseif(sources)
    ii_unity(${target})
  endif()

  string(REPLACE ";" "," allowed_list "${allowed}")
  set(stamp ${CMAKE_BINARY_DIR}/layers/${folder}.checked)
  add_custom_command(OUTPUT ${stamp}
    COMMAND ${CMAKE_COMMAND} -DROOT=${PROJECT_SOURCE_DIR}/src -DFOLDER=${folder} -DALLOWED=${allowed_list}
            -DSTAMP=${stamp} -P ${II_LAYER_SCRIPT}
    DEPENDS ${files} ${II_LAYER_SCRIPT}
    COMMENT "Checking the includes of src/${folder}" VERBATIM)
  add_custom_target(${target}_includes DEPENDS ${stamp})
  add_dependencies(${target} ${target}_includes)
endfunction()
