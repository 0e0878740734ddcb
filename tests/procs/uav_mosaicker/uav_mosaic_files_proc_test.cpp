// uav_mosaic_files as a new user runs it: a folder and --out, no other flag.
// It must read the stills settings (config/procs/uav_mosaic_files.yaml), say
// so, and register the photos as with --config. Real photos from
// ../shared/data (skipped with a message when absent).
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <string>

#include "vloc/testing/subprocess.h"

namespace vloc {
namespace {

using testing::BinPath;
using testing::Subprocess;

const char* kSeneca = "../shared/data/real/uav_seneca/images";

// The first n photos of a survey copied to a fresh folder.
std::string FirstPhotos(const std::string& from, size_t n, const std::string& name) {
  namespace fs = std::filesystem;
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(from)) files.push_back(e.path());
  std::sort(files.begin(), files.end());
  const fs::path dir = fs::path(::testing::TempDir()) / ("uav_mosaic_files_" + std::to_string(getpid()) + "_" + name);
  fs::create_directories(dir);
  for (size_t i = 0; i < n && i < files.size(); ++i)
    fs::copy_file(files[i], dir / files[i].filename(), fs::copy_options::overwrite_existing);
  return dir.string();
}

TEST(UavMosaicFiles, AFolderAloneGetsTheStillsSettings) {
  if (!std::filesystem::is_directory(kSeneca))
    GTEST_SKIP() << kSeneca << " absent (real data lives beside the repo, see ../shared/data/README.md): skipped";
  const std::string folder = FirstPhotos(kSeneca, 8, "seneca");
  const std::string out = folder + "/../uav_mosaic_files_" + std::to_string(getpid()) + ".png";
  Subprocess plain({BinPath("uav_mosaic_files"), "--out", out, folder});
  ASSERT_EQ(plain.WaitExit(300), 0) << plain.output();
  EXPECT_NE(plain.output().find("settings: "), std::string::npos) << plain.output();
  EXPECT_NE(plain.output().find("config/procs/uav_mosaic_files.yaml"), std::string::npos) << plain.output();
  EXPECT_NE(plain.output().find("registered 8 of 8 frames"), std::string::npos) << plain.output();
  Subprocess configured({BinPath("uav_mosaic_files"), "--config", "config/procs/uav_mosaic_files.yaml", "--out", out,
                         folder});
  ASSERT_EQ(configured.WaitExit(300), 0) << configured.output();
  // The same photos, the same registrations (every per-photo line identical).
  auto photo_lines = [](const std::string& text) {
    std::string lines;
    size_t at = 0;
    while ((at = text.find(".jpg: ", at)) != std::string::npos) {
      const size_t end = text.find('\n', at);
      lines += text.substr(at, end - at) + "\n";
      at = end;
    }
    return lines;
  };
  EXPECT_EQ(photo_lines(plain.output()), photo_lines(configured.output()));
  EXPECT_FALSE(photo_lines(plain.output()).empty());
  std::filesystem::remove_all(folder);
}

}  // namespace
}  // namespace vloc
