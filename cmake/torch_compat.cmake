# The build side of the differences between LibTorch builds (src/common/torch_compat.h holds
# the C++ side). Included right after find_package(Torch), before any target exists.
#
# LibTorch's CMake files look for its libraries with find_library, where the system's folders
# come before the hint of its own: with Debian's libtorch-dev installed, a PyPI LibTorch got
# Debian's libc10.so on its link line unless its own prefix comes first in CMAKE_PREFIX_PATH
# (scripts/gpu/build.sh does that). Refuse a mixed configuration rather than build one.
if(EXISTS ${TORCH_INSTALL_PREFIX}/lib/libc10.so)  # a self-contained LibTorch (PyPI, zip)
  get_filename_component(own_lib_dir ${TORCH_INSTALL_PREFIX}/lib REALPATH)
  foreach(var TORCH_LIBRARY c10_LIBRARY)
    get_filename_component(found_dir "${${var}}" DIRECTORY)
    get_filename_component(found_dir "${found_dir}" REALPATH)
    if(NOT found_dir STREQUAL own_lib_dir)
      message(FATAL_ERROR "LibTorch from ${TORCH_INSTALL_PREFIX}, but ${var} is ${${var}} (another "
        "LibTorch installation): put ${TORCH_INSTALL_PREFIX} first in CMAKE_PREFIX_PATH")
    endif()
  endforeach()
endif()

# PyPI's LibTorch 2.x ships the headers of the third-party libraries it was built with, fmt 12
# among them, in its include folder. That folder is searched before the system's, so <fmt/...>
# would be fmt 12 while the program links Debian's fmt 9 and the spdlog built against it:
# spdlog's headers do not compile with fmt 12, and code that did would mix two fmts. Links to
# the system's fmt and spdlog headers, searched before LibTorch's folder, keep every file on
# the fmt of the libraries it links. (Debian's own LibTorch bundles no fmt: nothing changes.)
set(II_TORCH_BUNDLES_FMT OFF)
foreach(dir ${TORCH_INCLUDE_DIRS})
  if(EXISTS ${dir}/fmt/core.h)
    set(II_TORCH_BUNDLES_FMT ON)
  endif()
endforeach()
if(II_TORCH_BUNDLES_FMT)
  set(II_SYSTEM_FIRST ${CMAKE_BINARY_DIR}/system-headers-first)
  foreach(pair "fmt;fmt::fmt" "spdlog;spdlog::spdlog")
    list(GET pair 0 name)
    list(GET pair 1 target)
    get_target_property(dirs ${target} INTERFACE_INCLUDE_DIRECTORIES)
    find_path(II_${name}_HEADERS ${name} PATHS ${dirs} NO_DEFAULT_PATH REQUIRED)
    file(MAKE_DIRECTORY ${II_SYSTEM_FIRST})
    file(CREATE_LINK ${II_${name}_HEADERS}/${name} ${II_SYSTEM_FIRST}/${name} SYMBOLIC)
  endforeach()
  # On LibTorch's own target, so that only files that use LibTorch see it: the torch-free ones
  # compile exactly as in the Debian build (and share its compiler cache).
  get_target_property(torch_includes torch INTERFACE_INCLUDE_DIRECTORIES)
  set_target_properties(torch PROPERTIES INTERFACE_INCLUDE_DIRECTORIES "${II_SYSTEM_FIRST};${torch_includes}")
  message(STATUS "LibTorch bundles fmt headers: the system's fmt and spdlog come first (${II_SYSTEM_FIRST})")
endif()

# PyPI's LibTorch 2.x also carries and exports (without symbol versions) parts of GCC 13's
# libstdc++ that its build machine's older system library lacks, std::filesystem among them.
# The dynamic linker binds each symbol to the first library in the program's search order that
# defines it, and an unversioned definition satisfies our versioned references: with
# libtorch.so listed before libstdc++.so.6, our calls went to LibTorch's copies. Its
# std::filesystem::remove_all calls recursive_directory_iterator::__erase, a GCC 13 member that
# it leaves as a weak undefined symbol and that Debian 12's libstdc++ (GCC 12) does not define:
# the call jumps to address 0 (docs/reliability.md). Listing libstdc++.so.6 first in every
# program binds the standard library's symbols to the standard library, for our code and for
# every library the program loads. Harmless with Debian's LibTorch, so done for both.
# By its file name, libstdc++.so.6, not -lstdc++: a compiler whose own folder holds only the
# static libstdc++.a (the lent GPU machines' CXX=/opt/gcc/bin/g++) would take that archive,
# from which nothing is needed yet at that point of the link, and the shared library would
# again come after libtorch.so.
add_link_options("LINKER:--push-state,--no-as-needed,-l:libstdc++.so.6,--pop-state")
