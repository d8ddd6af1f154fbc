// common/files.h: the temporary folder (the atomic writes are tested through every writer).
#include <gtest/gtest.h>

#include <fstream>

#include "common/files.h"

namespace ii {
namespace {

namespace fs = std::filesystem;

TEST(TemporaryFolder, IsFreshAndGoesWithEverythingInIt) {
  fs::path kept;
  {
    const TemporaryFolder a("ii-files-test"), b("ii-files-test");
    EXPECT_NE(a.path(), b.path());
    EXPECT_TRUE(fs::is_directory(a.path()));
    EXPECT_TRUE(fs::is_empty(a.path()));
    EXPECT_EQ(a.path().parent_path(), fs::temp_directory_path());
    EXPECT_EQ(a.path().filename().string().rfind("ii-files-test-", 0), 0u);
    fs::create_directories(a.path() / "frames");
    std::ofstream(a.path() / "frames" / "0000.png") << "x";
    kept = a.path();
  }
  EXPECT_FALSE(fs::exists(kept));
}

}  // namespace
}  // namespace ii
