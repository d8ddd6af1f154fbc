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

# A LibTorch translation unit pays seconds before any code of ours (the precompiled header's
# 375 MB, LibTorch's templates instantiated again in each file): the LibTorch targets compile
# their files in batches, one translation unit per batch (CMake's unity build; docs/benchmarks.md,
# "CI on a fresh machine"). Files with options of their own (the kernels compiled for an
# instruction set) stay alone, as CMake leaves them. Off for a quicker rebuild of one file.
option(INSTAINPAINT_UNITY_BUILD "Compile the LibTorch targets' files in batches" ON)
set(INSTAINPAINT_UNITY_BATCH_SIZE 8 CACHE STRING "Files per batch of a LibTorch target's unity build")
#   ii_torch_target(<target>): the shared precompiled LibTorch header and the batches.
function(ii_torch_target target)
  get_property(pch_owner GLOBAL PROPERTY II_PCH_OWNER)
  if(pch_owner)
    target_precompile_headers(${target} REUSE_FROM ${pch_owner})
  else()
    target_precompile_headers(${target} PUBLIC ${PROJECT_SOURCE_DIR}/src/common/torch.h)
    set_property(GLOBAL PROPERTY II_PCH_OWNER ${target})
  endif()
  if(INSTAINPAINT_UNITY_BUILD)
    set_target_properties(${target} PROPERTIES UNITY_BUILD ON UNITY_BUILD_BATCH_SIZE ${INSTAINPAINT_UNITY_BATCH_SIZE})
  endif()
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
