// Programs that link LibTorch use the C++ standard library's own code (cmake/torch_compat.cmake).
// PyPI's LibTorch exports copies of parts of GCC 13's libstdc++; bound to those, Debian 12's
// programs crashed in std::filesystem::remove_all (a call to address 0; docs/reliability.md).
#include <dlfcn.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <system_error>

#include "common/torch.h"
#include "test_support.h"

namespace ii {
namespace {

namespace fs = std::filesystem;

// The library that defines the function this program calls through `function`.
std::string defining_library(void* function) {
  Dl_info info{};
  if (dladdr(function, &info) == 0 || info.dli_fname == nullptr) return "(unknown)";
  return fs::path(info.dli_fname).filename().string();
}

TEST(StandardLibrary, FilesystemCallsBindToLibstdcxxNotToLibTorch) {
  ASSERT_GT(torch::ones({1}).item<float>(), 0.f);  // LibTorch is linked and loaded
  using RemoveAll = std::uintmax_t (*)(const fs::path&, std::error_code&);
  const RemoveAll remove_all = &fs::remove_all;
  fs::path (*const temp_directory_path)() = &fs::temp_directory_path;
  EXPECT_THAT(defining_library(reinterpret_cast<void*>(remove_all)), testing::StartsWith("libstdc++.so"));
  EXPECT_THAT(defining_library(reinterpret_cast<void*>(temp_directory_path)), testing::StartsWith("libstdc++.so"));
}

TEST(StandardLibrary, RemoveAllRemovesANestedTree) {
  const fs::path root = test::temp_dir("remove-all") / "tree";
  fs::create_directories(root / "a" / "b");
  test::write_bytes(root / "a" / "b" / "file", "x");
  test::write_bytes(root / "top", "y");
  std::error_code ec;
  EXPECT_EQ(fs::remove_all(root, ec), 5u);  // tree, a, b, file, top
  EXPECT_FALSE(ec) << ec.message();
  EXPECT_FALSE(fs::exists(root));
}

}  // namespace
}  // namespace ii
