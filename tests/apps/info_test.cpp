// `specula info`, `ls` and `synth-db` through the CLI.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "specula/codec/rgl_bsdf.h"
#include "specula/store/store.h"
#include "test_support.h"

using namespace specula;
using specula::test::run_specula;

TEST(SynthDbCli, SameSeedSameDatabaseAndInfoDescribesIt) {
  test::ScratchDir dir;
  auto a = dir / "a.h5", b = dir / "b.h5", c = dir / "c.h5";
  ASSERT_EQ(run_specula("-q synth-db -o '" + a.string() + "' --images 3 --size 20x30 --seed 5").status, 0);
  ASSERT_EQ(run_specula("-q synth-db -o '" + b.string() + "' --images 3 --size 20x30 --seed 5").status, 0);
  ASSERT_EQ(run_specula("-q synth-db -o '" + c.string() + "' --images 3 --size 20x30 --seed 6").status, 0);
  auto sa = store::Store::open(a), sb = store::Store::open(b), sc = store::Store::open(c);
  ASSERT_EQ(sa.images(), (std::vector<std::string>{"synth0", "synth1", "synth2"}));
  EXPECT_EQ(sa.read_image("synth2").data, sb.read_image("synth2").data);
  EXPECT_NE(sa.read_image("synth2").data, sc.read_image("synth2").data);

  auto ls = run_specula("ls '" + a.string() + "'");
  EXPECT_EQ(std::count(ls.output.begin(), ls.output.end(), '\n'), 3) << ls.output;
  auto info = run_specula("info '" + a.string() + "' synth1 --json");
  ASSERT_EQ(info.status, 0) << info.output;
  EXPECT_NE(info.output.find("\"height\":20,\"width\":30,\"bands\":31"), std::string::npos) << info.output;
  EXPECT_NE(info.output.find("\"importer\":\"synth-db\""), std::string::npos) << info.output;
  const std::uint64_t valid = sa.image_info("synth1").valid_pixels;
  EXPECT_NE(info.output.find("\"valid_pixels\":" + std::to_string(valid)), std::string::npos) << info.output;
  if (std::system("/usr/bin/python3 -c 'import json' >/dev/null 2>&1") == 0) {
    auto js = run_specula("info '" + a.string() +
                          "' --json | /usr/bin/python3 -c 'import json,sys; d=json.load(sys.stdin); "
                          "sys.exit(0 if len(d[\"objects\"]) == 3 else 1)'");
    EXPECT_EQ(js.status, 0) << js.output;
  }
}

TEST(SynthDbCli, OutOfRangeOptionsAreOneLineAndWriteNothing) {
  test::ScratchDir dir;
  for (const char* bad : {"--size 0x10", "--size 10", "--images 0", "--noise 2", "--wavelengths 700:400:10",
                          "--compression zip", "--prefix ../x"}) {
    auto r = run_specula(std::string("-q synth-db -o '") + (dir / "x.h5").string() + "' " + bad);
    EXPECT_NE(r.status, 0) << bad;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << bad << ": " << r.output;
    EXPECT_FALSE(std::filesystem::exists(dir / "x.h5")) << bad;
  }
}

TEST(InfoCli, MissingStoreAndObject) {
  test::ScratchDir dir;
  auto r = run_specula("info '" + (dir / "none.h5").string() + "'");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("none.h5: no such file"), std::string::npos) << r.output;
}

// A grid imported from a .bsdf carries its file's parameterisation; info says so, in text and JSON, with the sizes read
// from the file itself; a grid made otherwise says none.
TEST(InfoCli, GridsSayWhetherTheyCarryTheirSourcesParameterisation) {
  test::ScratchDir dir;
  const std::string db = "'" + (dir / "s.h5").string() + "'", bsdf = "'" + (dir / "src.bsdf").string() + "'";
  ASSERT_EQ(run_specula("-q synth-brdf blue-paint --wavelengths 400:700:50 -o " + db + ":plain").status, 0);
  auto r = run_specula("-q export " + db + ":plain -o " + bsdf + " --theta-i 4 --resolution 12");
  ASSERT_EQ(r.status, 0) << r.output;
  ASSERT_EQ(run_specula("-q import " + bsdf + " -o " + db + " --name back").status, 0);
  const codec::RglBsdf file = codec::read_rgl_bsdf(dir / "src.bsdf");
  const std::string expected = "parameterisation: source tables (RGL), " + std::to_string(file.theta_i.size()) +
                               " theta_i, ndf " + std::to_string(file.ndf_width) + "x" +
                               std::to_string(file.ndf_height) + ", vndf " + std::to_string(file.vndf_width) +
                               "^2, 12^2 sample grid";
  ASSERT_EQ(file.vndf_width, file.vndf_height);

  r = run_specula("info " + db);
  ASSERT_EQ(r.status, 0) << r.output;
  const auto line_of = [&](const std::string& name) {
    const std::size_t at = r.output.find("grid        " + name + " ");
    return at == std::string::npos ? std::string() : r.output.substr(at, r.output.find('\n', at) - at);
  };
  EXPECT_NE(line_of("back").find(expected), std::string::npos) << r.output;
  EXPECT_NE(line_of("plain").find("parameterisation: none"), std::string::npos) << r.output;
  r = run_specula("info " + db + " back");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find(expected), std::string::npos) << r.output;

  r = run_specula("info " + db + " --json");
  ASSERT_EQ(r.status, 0) << r.output;
  const nlohmann::json j = nlohmann::json::parse(r.output);
  std::map<std::string, nlohmann::json> grids;
  for (const auto& o : j.at("objects"))
    if (o.at("kind") == "grid") grids[o.at("name").get<std::string>()] = o;
  ASSERT_EQ(grids.size(), 2u);
  EXPECT_TRUE(grids["plain"].at("parameterisation").is_null());
  const nlohmann::json p = grids["back"].at("parameterisation");
  EXPECT_EQ(p.at("theta_i").get<std::vector<float>>(), file.theta_i);
  EXPECT_EQ(p.at("ndf").at("width").get<std::size_t>(), file.ndf_width);
  EXPECT_EQ(p.at("vndf").at("height").get<std::size_t>(), file.vndf_height);
  EXPECT_EQ(p.at("resolution").get<std::size_t>(), file.resolution);
  EXPECT_EQ(grids["back"].at("bands").get<std::size_t>(), 7u);
  r = run_specula("info " + db + " plain --json");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_TRUE(nlohmann::json::parse(r.output).at("parameterisation").is_null()) << r.output;
}
