// uav_mosaic_files as a new user runs it: a folder and --out, no other flag.
// It must read the stills settings (config/procs/uav_mosaic_files.yaml), say
// so, and register the photos as with --config; --self-calibrate refuses
// what it cannot do in one line, writing no camera; --height-reference is
// checked before the run. Real photos from
// ../shared/data (skipped with a message when absent).
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

#include "vloc/testing/subprocess.h"

namespace vloc {
namespace {

using testing::BinPath;
using testing::CountOccurrences;
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

// --self-calibrate's refusals, each one line naming the problem, exit 1 and
// no camera file: with --split (two views have no height ties); a survey
// of one strip (its links chain the heights exactly: no tie to disagree,
// nothing to tell a lens by); a camera file that cannot be written (found
// before the survey's first run, not after it).
TEST(UavMosaicFiles, SelfCalibrateRefusesInOneLine) {
  if (!std::filesystem::is_directory(kSeneca))
    GTEST_SKIP() << kSeneca << " absent (real data lives beside the repo, see ../shared/data/README.md): skipped";
  namespace fs = std::filesystem;
  const std::string strip = FirstPhotos(kSeneca, 6, "strip");
  const std::string camera = strip + "/../uav_mosaic_files_cam_" + std::to_string(getpid()) + ".yaml";
  const std::string out = strip + "/../uav_mosaic_files_sc_" + std::to_string(getpid()) + ".png";
  std::vector<std::string> photos;
  for (const auto& e : fs::directory_iterator(strip)) photos.push_back(e.path().string());
  std::sort(photos.begin(), photos.end());

  Subprocess split({BinPath("uav_mosaic_files"), "--split", "--self-calibrate", camera, "--out", out, photos[0]});
  EXPECT_EQ(split.WaitExit(60), 1) << split.output();
  EXPECT_EQ(CountOccurrences(split.output(), "--self-calibrate needs a survey"), 1) << split.output();

  Subprocess one_strip({BinPath("uav_mosaic_files"), "--self-calibrate", camera, "--out", out, strip});
  EXPECT_EQ(one_strip.WaitExit(300), 1) << one_strip.output();
  EXPECT_EQ(CountOccurrences(one_strip.output(), "the lens cannot be self-calibrated: "), 1) << one_strip.output();
  EXPECT_EQ(CountOccurrences(one_strip.output(), "registered "), 0) << "the survey ran after the refusal";

  const std::string unwritable = strip + "/no_such_folder/cam.yaml";
  Subprocess cannot_write({BinPath("uav_mosaic_files"), "--self-calibrate", unwritable, "--out", out, strip});
  EXPECT_EQ(cannot_write.WaitExit(60), 1) << cannot_write.output();
  EXPECT_EQ(CountOccurrences(cannot_write.output(), "--self-calibrate: cannot write " + unwritable), 1)
      << cannot_write.output();
  EXPECT_EQ(CountOccurrences(cannot_write.output(), "lens self-calibration: a first run"), 0) << "refused after the run";
  EXPECT_FALSE(fs::exists(camera));
  EXPECT_FALSE(fs::exists(unwritable));
  fs::remove_all(strip);
  fs::remove(camera);
  fs::remove(out);
}

// --height-reference: read before the survey runs (a bad file, or --split's
// two views without a metric scale: one line, exit 1, no survey); a good one
// prints the heights and the altitude tags against it.
TEST(UavMosaicFiles, HeightReferenceIsCheckedBeforeTheRunAndCompared) {
  if (!std::filesystem::is_directory(kSeneca))
    GTEST_SKIP() << kSeneca << " absent (real data lives beside the repo, see ../shared/data/README.md): skipped";
  namespace fs = std::filesystem;
  const std::string folder = FirstPhotos(kSeneca, 8, "reference");
  const std::string out = folder + "/../uav_mosaic_files_ref_" + std::to_string(getpid()) + ".png";
  const std::string reference = VLOC_SOURCE_DIR "/tests/data/mosaic/uav_seneca_reference_heights.tsv";
  const std::string missing = folder + "/no_such_heights.tsv";
  Subprocess bad({BinPath("uav_mosaic_files"), "--height-reference", missing, "--out", out, folder});
  EXPECT_EQ(bad.WaitExit(60), 1) << bad.output();
  EXPECT_EQ(CountOccurrences(bad.output(), "height reference " + missing + ": cannot be read"), 1) << bad.output();
  EXPECT_EQ(CountOccurrences(bad.output(), "registered "), 0) << "the survey ran before the refusal";
  Subprocess split({BinPath("uav_mosaic_files"), "--split", "--height-reference", reference, "--out", out,
                    folder + "/IMG_0447.jpg"});
  EXPECT_EQ(split.WaitExit(60), 1) << split.output();
  EXPECT_EQ(CountOccurrences(split.output(), "--height-reference needs a geotagged survey"), 1) << split.output();
  EXPECT_FALSE(fs::exists(out));

  Subprocess good({BinPath("uav_mosaic_files"), "--height-reference", reference, "--out", out, folder});
  EXPECT_EQ(good.WaitExit(300), 0) << good.output();
  // The first photo (a cropped frame) is not in the reference: 7 of the 8.
  EXPECT_EQ(CountOccurrences(good.output(), "height vs the reference heights above the ground over 7 frames"), 1)
      << good.output();
  EXPECT_EQ(CountOccurrences(good.output(), "; the altitude tags "), 1) << good.output();
  fs::remove_all(folder);
  fs::remove(out);
  fs::remove(fs::path(out).replace_extension(".pgw"));
}

}  // namespace
}  // namespace vloc
