# Optional CUDA rasterizer kernels (src/render/cuda/*.cu). They use raw device pointers, so
# they build with nvcc alone, whether the LibTorch found is a CUDA build or not; without a
# CUDA compiler this file does nothing and the CPU build is unchanged.
include(CheckLanguage)
if(NOT DEFINED CMAKE_CUDA_COMPILER AND NOT DEFINED ENV{CUDACXX} AND EXISTS /usr/local/cuda/bin/nvcc)
  set(CMAKE_CUDA_COMPILER /usr/local/cuda/bin/nvcc)
endif()
check_language(CUDA)
if(CMAKE_CUDA_COMPILER)
  if(NOT DEFINED CMAKE_CUDA_ARCHITECTURES)
    set(CMAKE_CUDA_ARCHITECTURES 80 90)
  endif()
  enable_language(CUDA)
  find_package(CUDAToolkit REQUIRED)
  if(II_CCACHE_LAUNCHER AND NOT CMAKE_CUDA_COMPILER_LAUNCHER)
    set(CMAKE_CUDA_COMPILER_LAUNCHER ${II_CCACHE_LAUNCHER})  # as the C++ files (CMakeLists.txt)
  endif()
  file(GLOB CUDA_RENDER_SOURCES CONFIGURE_DEPENDS ${PROJECT_SOURCE_DIR}/src/render/cuda/*.cu)
  add_library(instainpaint_cuda STATIC ${CUDA_RENDER_SOURCES})
  target_include_directories(instainpaint_cuda PUBLIC ${PROJECT_SOURCE_DIR}/src)
  set_target_properties(instainpaint_cuda PROPERTIES
    CUDA_STANDARD 17 CUDA_STANDARD_REQUIRED ON POSITION_INDEPENDENT_CODE ON)
  # The project-wide -Wall -Wextra are host-compiler flags that nvcc rejects: pass them to
  # its host compiler instead.
  set_property(TARGET instainpaint_cuda PROPERTY COMPILE_OPTIONS "")
  target_compile_options(instainpaint_cuda PRIVATE
    --expt-relaxed-constexpr -Xcompiler=-Wall,-Wextra,-Wno-unused-parameter)
  # Static runtime: binaries run without the toolkit's library folder on the loader path.
  target_link_libraries(instainpaint_cuda PUBLIC CUDA::cudart_static)
  target_link_libraries(ii_render PUBLIC instainpaint_cuda)
  target_compile_definitions(ii_render PUBLIC INSTAINPAINT_HAS_CUDA_KERNELS)
  if(CMAKE_CUDA_ARCHITECTURES)
    set(II_CUDA_ARCHS "architectures ${CMAKE_CUDA_ARCHITECTURES}")
  else()  # a CUDA LibTorch sets them from TORCH_CUDA_ARCH_LIST, as -gencode flags
    set(II_CUDA_ARCHS "LibTorch's architectures ${TORCH_CUDA_ARCH_LIST}")
  endif()
  message(STATUS "CUDA rasterizer kernels: on (${CMAKE_CUDA_COMPILER}, ${II_CUDA_ARCHS})")

elseif(INSTAINPAINT_REQUIRE_CUDA)
  message(FATAL_ERROR "INSTAINPAINT_REQUIRE_CUDA is on but no CUDA compiler was found (CMAKE_CUDA_COMPILER, CUDACXX)")
else()
  message(STATUS "CUDA rasterizer kernels: off (no CUDA compiler)")
endif()
