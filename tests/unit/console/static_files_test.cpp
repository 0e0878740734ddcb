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

TEST(JsonDepthWithin, CountsBracketsOutsideStringsOnly) {
  EXPECT_TRUE(JsonDepthWithin(R"({"a":[1,{"b":[2]}]})", 4));
  EXPECT_FALSE(JsonDepthWithin(R"({"a":[1,{"b":[2]}]})", 3));
  EXPECT_TRUE(JsonDepthWithin(R"({"s":"[[[[[[\"{{{{"})", 1));
  EXPECT_FALSE(JsonDepthWithin(std::string(70000, '[') + std::string(70000, ']'), 16));
  EXPECT_TRUE(JsonDepthWithin(std::string(16, '[') + std::string(16, ']'), 16));
  EXPECT_TRUE(JsonDepthWithin("", 3));
}

TEST(HostAllowed, AddressesLocalhostAndListedNamesOnly) {
  const std::vector<std::string> none, station = {"ground.example"};
  for (const std::string h : std::vector<std::string>{"127.0.0.1", "127.0.0.1:8765", "localhost:8765", "LOCALHOST", "[::1]:8765", "10.1.2.3"})
    EXPECT_TRUE(HostAllowed(h, none)) << h;
  for (const std::string h : std::vector<std::string>{"", "attacker.example", "attacker.example:8765", "127.0.0.1.attacker.example",
                              "localhost.attacker.example", "[::1"})
    EXPECT_FALSE(HostAllowed(h, none)) << h;
  EXPECT_TRUE(HostAllowed("Ground.Example:8765", station));
  EXPECT_FALSE(HostAllowed("ground.example.attacker.example", station));
  EXPECT_EQ(HostOfAuthority("[::1]:8765"), "::1");
  EXPECT_EQ(HostOfAuthority("Example.ORG:80"), "example.org");
}

TEST(OriginAllowed, SameOriginOrListed) {
  const std::vector<std::string> none, dashboard = {"https://dash.example"};
  EXPECT_TRUE(OriginAllowed("http://127.0.0.1:8765", "127.0.0.1:8765", none));
  EXPECT_TRUE(OriginAllowed("http://LOCALHOST:8765", "localhost:8765", none));
  EXPECT_FALSE(OriginAllowed("http://127.0.0.1:9999", "127.0.0.1:8765", none));
  EXPECT_FALSE(OriginAllowed("http://attacker.example", "127.0.0.1:8765", none));
  EXPECT_FALSE(OriginAllowed("null", "127.0.0.1:8765", none));
  EXPECT_FALSE(OriginAllowed("file://127.0.0.1:8765", "127.0.0.1:8765", none));
  EXPECT_FALSE(OriginAllowed("http://127.0.0.1:8765", "", none));
  EXPECT_TRUE(OriginAllowed("https://dash.example", "10.0.0.2:8765", dashboard));
}

TEST(ConsoleServerOptions, RefusesHostsAndOriginsThatAreNot) {
  ConsoleServerOptions o;
  std::string error;
  EXPECT_TRUE(o.Check(&error)) << error;
  o.allowed_hosts = {"station:8765"};
  EXPECT_FALSE(o.Check(&error));
  EXPECT_NE(error.find("allowed_hosts"), std::string::npos);
  o.allowed_hosts = {"station"};
  o.allowed_origins = {"station"};
  EXPECT_FALSE(o.Check(&error));
  EXPECT_NE(error.find("allowed_origins"), std::string::npos);
  o.allowed_origins = {"https://station"};
  o.max_json_depth = 1;
  EXPECT_FALSE(o.Check(&error));
}

}  // namespace
}  // namespace vloc
