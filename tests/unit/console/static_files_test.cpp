// The console's file rules (libs/console): decoding, what resolves inside
// the web folder and what never does, query parsing, option checks.
#include "vloc/console/static_files.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "vloc/console/console_server.h"

namespace vloc {
namespace {

TEST(PercentDecode, DecodesOnceAndRejectsMalformedEscapes) {
  std::string out;
  ASSERT_TRUE(PercentDecode("/a%20b%2e%2E%2F", &out));
  EXPECT_EQ(out, "/a b../");
  ASSERT_TRUE(PercentDecode("%252e", &out));
  EXPECT_EQ(out, "%2e");
  for (const char* bad : {"%", "%2", "%zz", "abc%g0"}) EXPECT_FALSE(PercentDecode(bad, &out)) << bad;
}

class StaticFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() / ("vloc_static_files_" + std::to_string(::getpid()));
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_ / "web" / "css");
    std::ofstream(dir_ / "web" / "index.html") << "index";
    std::ofstream(dir_ / "web" / "css" / "a.css") << "css";
    std::ofstream(dir_ / "secret") << "secret";
    std::filesystem::create_symlink(dir_ / "secret", dir_ / "web" / "out");
    root_ = std::filesystem::canonical(dir_ / "web");
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  bool Resolves(const std::string& url, std::string* why = nullptr) {
    std::filesystem::path file;
    std::string w;
    const bool ok = ResolveStaticPath(root_, url, &file, &w);
    if (why) *why = w;
    return ok;
  }
  std::filesystem::path dir_, root_;
};

TEST_F(StaticFiles, ServesItsOwnFiles) {
  EXPECT_TRUE(Resolves("/"));
  EXPECT_TRUE(Resolves("/index.html"));
  EXPECT_TRUE(Resolves("/css/a.css"));
  EXPECT_TRUE(Resolves("/css%2Fa.css"));
}

TEST_F(StaticFiles, NeverLeavesTheFolder) {
  for (const char* url : {"/../secret", "/css/../../secret", "/%2e%2e/secret", "/%2E%2E%2fsecret", "/out", "secret", "",
                          "//secret", "/css/", "/css", "/.", "/.hidden", "/a%00b", "/a\\..\\secret", "/%zz"}) {
    std::string why;
    EXPECT_FALSE(Resolves(url, &why)) << url;
    EXPECT_FALSE(why.empty()) << url;
  }
  std::string why;
  Resolves("/out", &why);
  EXPECT_EQ(why, "outside the web folder");
}

TEST(ContentType, ByExtension) {
  EXPECT_EQ(ContentTypeOf("a.js"), "text/javascript; charset=utf-8");
  EXPECT_EQ(ContentTypeOf("a.png"), "image/png");
  EXPECT_EQ(ContentTypeOf("a.bin"), "application/octet-stream");
}

TEST(ParseQuery, DecodesPairsAndSkipsMalformedOnes) {
  const auto q = ParseQuery("site=3&pair=%31&bad&x=%zz&empty=");
  EXPECT_EQ(q.at("site"), "3");
  EXPECT_EQ(q.at("pair"), "1");
  EXPECT_EQ(q.count("bad"), 0u);
  EXPECT_EQ(q.count("x"), 0u);
  EXPECT_EQ(q.at("empty"), "");
}

TEST(ConsoleServerOptions, DefaultsPassAndBadValuesNameTheKey) {
  ConsoleServerOptions o;
  std::string error;
  EXPECT_TRUE(o.Check(&error)) << error;
  o.bind_address = "localhost:80";
  EXPECT_FALSE(o.Check(&error));
  EXPECT_NE(error.find("bind_address"), std::string::npos);
  o = ConsoleServerOptions();
  o.port = -1;
  EXPECT_FALSE(o.Check(&error));
  EXPECT_NE(error.find("port"), std::string::npos);
}

TEST(ConsoleServer, MayActOnlyWithTheTokenOrOnLoopbackWithoutOne) {
  ConsoleServerOptions o;
  o.web_root = std::filesystem::temp_directory_path().string();
  o.port = 0;
  ConsoleServer open(o);
  std::string error;
  ASSERT_TRUE(open.Start(&error)) << error;
  EXPECT_TRUE(open.MayAct(""));
  o.token = "t0k";
  ConsoleServer guarded(o);
  ASSERT_TRUE(guarded.Start(&error)) << error;
  EXPECT_FALSE(guarded.MayAct(""));
  EXPECT_FALSE(guarded.MayAct("t0"));
  EXPECT_FALSE(guarded.MayAct("t0k "));
  EXPECT_TRUE(guarded.MayAct("t0k"));
  EXPECT_GT(guarded.port(), 0);
}

}  // namespace
}  // namespace vloc
