// Issue 16, item 3: limits before allocation, physically impossible log values, and usage errors
// that were exit 2 or silently ignored. Each case reproduces a finding of the bad-input sweep.
#include <cstdint>
#include <fstream>
#include <string>
#include <vector>

#include "testing/testing.h"

namespace ssiu {
namespace {

using ::testing::HasSubstr;
using Result = testing::SsiuResult;

void Put32(std::vector<uint8_t>* b, uint32_t v) {
  for (int s = 24; s >= 0; s -= 8) b->push_back(static_cast<uint8_t>(v >> s));
}

// A PNG whose IHDR declares w x h 8-bit grey pixels, followed by `idat_bytes` of (junk) IDAT data:
// the sweep's 8 MB file declaring 65536 x 65536 allocated 8.6 GB.
void WriteDeclaredPng(const std::string& path, uint32_t w, uint32_t h, size_t idat_bytes) {
  std::vector<uint8_t> b = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  Put32(&b, 13);
  for (char c : std::string("IHDR")) b.push_back(static_cast<uint8_t>(c));
  Put32(&b, w);
  Put32(&b, h);
  for (uint8_t v : {8, 0, 0, 0, 0}) b.push_back(v);  // depth 8, grey, deflate, no filter, no interlace
  Put32(&b, 0);                                      // CRC (not checked before the size)
  Put32(&b, static_cast<uint32_t>(idat_bytes));
  for (char c : std::string("IDAT")) b.push_back(static_cast<uint8_t>(c));
  b.resize(b.size() + idat_bytes, 0);
  Put32(&b, 0);
  std::ofstream(path, std::ios::binary)
      .write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
}

TEST(LimitsCli, ImageDeclaringTooManyPixelsIsRefusedBeforeAllocation) {
  const std::string d = testing::TempDir("limits_cli_png");
  WriteDeclaredPng(d + "/big.png", 65536, 65536, 8 << 20);
  // Refused from the header, before the 8.6 GB buffer (exit 2, bad_alloc, under a memory cap).
  const Result r = testing::RunSsiu("detect " + d + "/big.png");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_THAT(r.output, HasSubstr("big.png: declares 65536 x 65536 pixels, more than the limit of 16384"));
  // The limit is configurable: a 512 x 512 frame refused under a 256 px limit.
  WriteDeclaredPng(d + "/small.png", 512, 512, 100);
  const Result s = testing::RunSsiu("detect " + d + "/small.png");
  EXPECT_THAT(s.output, ::testing::Not(HasSubstr("per side")));
  std::string out2;
  testing::Run("SSIU_MAX_IMAGE_SIDE_PX=256 " + testing::SsiuProgram() + " detect " + d + "/small.png", &out2);
  EXPECT_THAT(out2, HasSubstr("more than the limit of 256 per side"));
}

TEST(LimitsCli, PhysicallyImpossibleGyroAndTemperatureValuesNameRowAndColumn) {
  // 1e300 deg/h gave status `fused` with NaN sigmas, 1e12 deg/h a bias of -39,424 deg/h.
  const std::string d = testing::TempDir("limits_cli_gyro");
  std::ofstream(d + "/st.csv") << "t_s,qw,qx,qy,qz\n0,1,0,0,0\n0.02,1,0,0,0\n";
  for (const std::string v : {"1e300", "1e12", "-4e6"}) {
    std::ofstream(d + "/g.csv") << "t_s,wx_dph,wy_dph,wz_dph\n0.01,1,2,3\n0.02,1," << v << ",3\n0.03,1,2,3\n";
    const Result r = testing::RunSsiu("fuse --gyro " + d + "/g.csv --st " + d + "/st.csv --json " + d + "/f.json");
    EXPECT_EQ(r.status, 1) << v << "\n" << r.output;
    EXPECT_THAT(r.output, HasSubstr("g.csv: row 2, column 'wy_dph': " + v + " is physically impossible")) << v;
  }
  // A full-scale rate of a real FOG (500 deg/s = 1.8e6 deg/h) is not refused.
  std::ofstream(d + "/g.csv") << "t_s,wx_dph,wy_dph,wz_dph\n0.01,1,1.8e6,3\n0.02,1,2,3\n0.03,1,2,3\n";
  EXPECT_THAT(testing::RunSsiu("fuse --gyro " + d + "/g.csv --st " + d + "/st.csv").output,
              ::testing::Not(HasSubstr("physically impossible")));
  std::ofstream(d + "/t.csv") << "t_s,w_dph,temp_c,ref_dph\n0,1,20,0\n1,1,-300,0\n";
  std::ofstream(d + "/m.json") << R"({"terms": {"K00": 0.1}})";
  const Result t = testing::RunSsiu("fog compensate " + d + "/t.csv --model " + d + "/m.json --out " + d + "/c.csv");
  EXPECT_EQ(t.status, 1) << t.output;
  EXPECT_THAT(t.output, HasSubstr("row 2, column 'temp_c': -300 is physically impossible"));
}

TEST(LimitsCli, SolveUsageErrorsExitOne) {
  const std::string d = testing::TempDir("limits_cli_solve");
  // An overlay that is not a PNG was an OpenCV exception (exit 2) after the whole solve.
  Result r = testing::RunSsiu("solve f.png --camera c.json --overlay " + d + "/out.xyz");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_THAT(r.output, HasSubstr("out.xyz: unsupported extension '.xyz'"));
  // Two frames without --heads solved the first and ignored the second; now they are a batch
  // (tests/cli/batch_cli_test.cc), which needs its camera before any frame.
  r = testing::RunSsiu("solve f1.png f2.png --camera " + d + "/c.json");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_THAT(r.output, HasSubstr(d + "/c.json"));
}

}  // namespace
}  // namespace ssiu
