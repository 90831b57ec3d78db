#include "nmbake/job.hpp"

#include <gtest/gtest.h>

#include "test_util.hpp"

namespace nmbake {
namespace {

TEST(Job, ParsesDefaultsAndSeveralBakes) {
  test::TempDir dir;
  const std::string path = dir.file("job.toml");
  test::write_text(path, R"(
[defaults]
size = 512
samples = 16
green = "down"
front = "2%"
back = 0.25

[[bake]]
name = "a"
low = "meshes/low.obj"
high = "/abs/high.ply"
outputs = ["out/a.png", { path = "out/a.exr", format = "exr-half" }]
report = "out/a.json"

[[bake]]
low = "l.obj"
high = "h.obj"
outputs = ["b.tif"]
size = 64
hit = "nearest"
ignore_backfaces = true
bvh = "compact"
)");
  std::vector<BakeJob> jobs;
  const Status s = load_job_file(path, jobs);
  ASSERT_TRUE(s.is_ok()) << s.message();
  ASSERT_EQ(jobs.size(), 2u);
  const BakeOptions& a = jobs[0].options;
  EXPECT_EQ(jobs[0].name, "a");
  EXPECT_EQ(a.width, 512);
  EXPECT_EQ(a.samples, 16);
  EXPECT_EQ(a.encode.green, GreenChannel::down);
  EXPECT_EQ(a.rays.front.kind, Distance::Kind::percent);
  EXPECT_FLOAT_EQ(a.rays.front.value, 2.0f);
  EXPECT_EQ(a.rays.back.kind, Distance::Kind::absolute);
  EXPECT_FLOAT_EQ(a.rays.back.value, 0.25f);
  EXPECT_EQ(a.low_path, (dir.path() / "meshes/low.obj").string());
  EXPECT_EQ(a.high_paths, std::vector<std::string>{"/abs/high.ply"});
  ASSERT_EQ(a.outputs.size(), 2u);
  EXPECT_EQ(a.outputs[0].format, PixelFormat::png16);
  EXPECT_EQ(a.outputs[1].format, PixelFormat::exr_half);
  EXPECT_EQ(jobs[0].report_path, (dir.path() / "out/a.json").string());
  const BakeOptions& b = jobs[1].options;
  EXPECT_EQ(jobs[1].name, "bake 2");
  EXPECT_EQ(b.width, 64);
  EXPECT_EQ(b.samples, 16);  // from [defaults]
  EXPECT_EQ(b.rays.hit, HitRule::nearest);
  EXPECT_TRUE(b.rays.ignore_backfaces);
  EXPECT_EQ(b.bvh_memory, BvhMemory::compact);
  EXPECT_EQ(a.bvh_memory, BvhMemory::automatic);
  EXPECT_EQ(b.outputs[0].format, PixelFormat::tiff16);
}

// [[bake.pack]] tables are the pack option's text in another form: the same
// packs as pack = ["..."]; a table of another shape names its key.
TEST(Job, PackTablesAreThePackOptionsText) {
  test::TempDir dir;
  const std::string base = "[[bake]]\nlow = \"l.obj\"\nhigh = \"h.obj\"\noutputs = [\"m_<MAP>.png\"]\n";
  test::write_text(dir.file("a.toml"), base +
                                           "pack = [\"orm.png=r:ao,g:roughness,b:metallic,a:1\", "
                                           "\"mask.png=r:metallic,g:ao,b:0,a:1-roughness\"]\n");
  test::write_text(dir.file("b.toml"),
                   base +
                       "[[bake.pack]]\nfile = \"orm.png\"\nr = \"ao\"\ng = \"roughness\"\n"
                       "b = \"metallic\"\na = 1\n[[bake.pack]]\nfile = \"mask.png\"\n"
                       "r = \"metallic\"\ng = \"ao\"\nb = 0\na = \"1-roughness\"\n");
  std::vector<BakeJob> a, b;
  ASSERT_TRUE(load_job_file(dir.file("a.toml"), a).is_ok());
  const Status s = load_job_file(dir.file("b.toml"), b);
  ASSERT_TRUE(s.is_ok()) << s.message();
  ASSERT_EQ(b.front().options.packs.size(), 2u);
  EXPECT_EQ(a.front().options.packs, b.front().options.packs);
  test::write_text(dir.file("c.toml"), base + "[[bake.pack]]\nfile = \"orm.png\"\nred = \"ao\"\n");
  const Status c = load_job_file(dir.file("c.toml"), b);
  ASSERT_FALSE(c.is_ok());
  EXPECT_NE(c.message().find("c.toml:"), std::string::npos) << c.message();
  EXPECT_NE(c.message().find("unknown key \"red\""), std::string::npos) << c.message();
}

TEST(Job, RejectsUnknownKeysWithTheLine) {
  test::TempDir dir;
  const std::string path = dir.file("job.toml");
  test::write_text(path, "[[bake]]\nlow = \"l.obj\"\nhigh = \"h.obj\"\noutputs = [\"a.png\"]\nsampels = 4\n");
  std::vector<BakeJob> jobs;
  const Status s = load_job_file(path, jobs);
  ASSERT_FALSE(s.is_ok());
  EXPECT_NE(s.message().find(path + ":5"), std::string::npos) << s.message();
  EXPECT_NE(s.message().find("sampels"), std::string::npos);
}

TEST(Job, RejectsBadValuesAndSyntax) {
  test::TempDir dir;
  const std::string path = dir.file("job.toml");
  std::vector<BakeJob> jobs;
  test::write_text(path,
                   "[[bake]]\nlow = \"l.obj\"\nhigh = \"h.obj\"\noutputs = [\"a.png\"]\nspace = \"world\"\n");
  EXPECT_FALSE(load_job_file(path, jobs).is_ok());
  test::write_text(path, "[[bake]]\nlow = \"l.obj\"\nhigh = \"h.obj\"\noutputs = [\"a.bmp\"]\n");
  EXPECT_FALSE(load_job_file(path, jobs).is_ok());
  test::write_text(path,
                   "[[bake]]\nlow = \"l.obj\"\nhigh = \"h.obj\"\noutputs = [\"a.png\"]\nbvh = \"small\"\n");
  EXPECT_FALSE(load_job_file(path, jobs).is_ok());
  test::write_text(path, "[[bake]]\nlow = \"l.obj\"\noutputs = [\"a.png\"]\n");  // no high
  EXPECT_FALSE(load_job_file(path, jobs).is_ok());
  test::write_text(path, "[[bake]\nlow = \n");
  const Status s = load_job_file(path, jobs);
  ASSERT_FALSE(s.is_ok());
  EXPECT_NE(s.message().find(path), std::string::npos);
  EXPECT_FALSE(load_job_file(dir.file("missing.toml"), jobs).is_ok());
}

TEST(Job, DistanceWords) {
  Distance d;
  EXPECT_TRUE(parse_distance("auto", d));
  EXPECT_EQ(d.kind, Distance::Kind::automatic);
  EXPECT_TRUE(parse_distance("0.05", d));
  EXPECT_EQ(d.kind, Distance::Kind::absolute);
  EXPECT_TRUE(parse_distance("3%", d));
  EXPECT_EQ(d.kind, Distance::Kind::percent);
  EXPECT_FALSE(parse_distance("-1", d));
  EXPECT_FALSE(parse_distance("nan", d));
  EXPECT_FALSE(parse_distance("%", d));
  EXPECT_FALSE(parse_distance("1cm", d));
}

}  // namespace
}  // namespace nmbake
