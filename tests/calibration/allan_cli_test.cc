// `ssiu allan` end to end: the JSON contract, the plot, and one-line errors with exit status 1.
// Also the PNG plot helper on its own (a line drawn where the axes say it should be).
#include <cmath>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>

#include "core/json.h"
#include "core/rng.h"
#include "plot/plot.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

class AllanCli : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!std::filesystem::exists(testing::SsiuProgram())) GTEST_SKIP() << "the ssiu program is not built";
    dir_ = testing::TempDir("allan");
  }
  int Ssiu(const std::string& args, std::string* out) {
    return testing::Run(testing::SsiuProgram() + " allan " + args, out);
  }
  void Write(const std::string& name, const std::string& text) { std::ofstream(dir_ + "/" + name) << text; }
  std::string dir_;
};

TEST_F(AllanCli, LogToJsonAndPlot) {
  // 20 min at 50 Hz of white rate noise with N = 0.05 deg/sqrt(h) in deg/h, plus an unrelated column.
  const double fs = 50, n_dph = 0.05 * 60;  // deg/h*sqrt(s)
  Rng rng(21);
  {
    std::ofstream out(dir_ + "/log.csv");
    out << "t_s,g1_dph,temp_c\n";
    out.precision(12);
    for (int i = 0; i < 60000; ++i) out << i / fs << "," << 3.0 + n_dph * std::sqrt(fs) * rng.Normal() << ",25\n";
  }
  std::string out;
  const std::string json = dir_ + "/out.json", png = dir_ + "/out.png";
  ASSERT_EQ(Ssiu(dir_ + "/log.csv --column g1_dph --json " + json + " --plot " + png, &out), 0) << out;
  const Json j = ReadJsonFile(json);
  EXPECT_EQ(j["file"], dir_ + "/log.csv");
  EXPECT_EQ(j["column"], "g1_dph");
  EXPECT_EQ(j["rate_unit"], "deg/h");
  EXPECT_NEAR(j["sample_rate_hz"].get<double>(), fs, 1e-6);
  EXPECT_EQ(j["n"], 60000);
  const size_t k = j["tau_s"].size();
  ASSERT_GT(k, 30u);
  for (const char* key : {"adev", "adev_lo", "adev_hi", "edf", "noise", "model_adev"})
    EXPECT_EQ(j[key].size(), k) << key;
  // ADEV in deg/h: n / sqrt(tau) at the first point.
  EXPECT_NEAR(j["adev"][0].get<double>() / (n_dph / std::sqrt(1 / fs)), 1.0, 0.03);
  const Json& arw = j["terms"]["arw_deg_per_sqrt_h"];
  EXPECT_NEAR(arw["value"].get<double>(), 0.05, 0.005);
  EXPECT_GT(arw["sigma"].get<double>(), 0.0);
  ASSERT_EQ(arw["tau_range_s"].size(), 2u);
  EXPECT_TRUE(arw["significant"].get<bool>());
  for (const char* term : {"bias_instability_dph", "rrw_deg_per_h_per_sqrt_h", "quantization_arcsec",
                           "rate_ramp_deg_per_h2", "bias_instability_floor_dph"}) {
    EXPECT_TRUE(j["terms"].contains(term)) << term;
  }
  const cv::Mat img = cv::imread(png);
  EXPECT_EQ(img.cols, 960);
  EXPECT_EQ(img.rows, 680);
  // The human summary names the terms.
  EXPECT_THAT(out, ::testing::HasSubstr("angle random walk"));
}

TEST_F(AllanCli, BadInputExitsOneWithOneLine) {
  Write("log.csv", "t_s,g1_dph\n0,1\n0.1,2\n0.2,nan\n");
  Write("few.csv", "t_s,g1_dph\n0,1\n0.1,2\n0.2,3\n");
  std::string out;
  EXPECT_EQ(Ssiu(dir_ + "/log.csv --column g2_dph --json -", &out), 1);
  EXPECT_THAT(out, ::testing::HasSubstr("missing column 'g2_dph'"));
  EXPECT_EQ(Ssiu(dir_ + "/log.csv --column g1_dph --json -", &out), 1);
  EXPECT_THAT(out, ::testing::HasSubstr("row 3, column 'g1_dph'"));
  EXPECT_EQ(Ssiu(dir_ + "/few.csv --column g1_dph --json -", &out), 1);
  EXPECT_THAT(out, ::testing::HasSubstr("too few samples"));
  EXPECT_EQ(Ssiu(dir_ + "/missing.csv --column g1_dph", &out), 1);
  EXPECT_THAT(out, ::testing::HasSubstr("cannot open"));
  EXPECT_EQ(Ssiu("--json -", &out), 1);
  EXPECT_THAT(out, ::testing::HasSubstr("give either a LOG.csv"));
  EXPECT_EQ(Ssiu(dir_ + "/few.csv", &out), 1);
  EXPECT_THAT(out, ::testing::HasSubstr("--column NAME is required"));
  // Bad flag values: exit 1 naming the flag (a NaN or negative rate used to be ignored in favour of
  // t_s, an infinite one or a negative tau limit stopped the fit with an internal error, exit 2).
  for (const std::string flag : {"--sample-rate-hz nan", "--sample-rate-hz -5", "--sample-rate-hz inf",
                                 "--tau-min-s nan", "--tau-min-s -5", "--tau-max-s nan"}) {
    EXPECT_EQ(Ssiu(dir_ + "/few.csv --column g1_dph " + flag + " --json -", &out), 1) << flag << "\n" << out;
    EXPECT_THAT(out, ::testing::HasSubstr(flag.substr(0, flag.find(' ')) + ": must be a finite number >= 0")) << flag;
  }
}

TEST_F(AllanCli, RealCurveFileWithUnitAndChannel) {
  SSIU_REQUIRE_SHARED(path, "gyro/smac-avar/ln200_av.csv");
  std::string out;
  const std::string json = dir_ + "/ln200.json";
  EXPECT_EQ(Ssiu("--curve " + path + " --json " + json, &out), 1);  // several channels, no unit
  EXPECT_THAT(out, ::testing::HasSubstr("give --channel"));
  ASSERT_EQ(Ssiu("--curve " + path + " --channel 'Gyro. X' --unit rad/s --json " + json, &out), 0) << out;
  const Json j = ReadJsonFile(json);
  EXPECT_EQ(j["source"], "curve");
  EXPECT_EQ(j["channel"], "Gyro. X");
  EXPECT_EQ(j["edf_source"], "rel_error");
  const double arw = j["terms"]["arw_deg_per_sqrt_h"]["value"].get<double>();
  EXPECT_GT(arw, 0.02);  // LN-200 datasheet: 0.04..0.1 deg/sqrt(h)
  EXPECT_LT(arw, 0.25);
}

TEST(PlotPng, LogLogLineLandsWhereTheAxesSay) {
  const std::string dir = testing::TempDir("plot");
  PlotSeries s;
  s.x = {1, 10, 100};
  s.y = {10, 10, 10};
  s.color = {255, 0, 0};
  s.label = "flat";
  PlotSeries e;
  e.x = {3};
  e.y = {3};
  e.y_lo = {1};
  e.y_hi = {50};
  e.color = {0, 0, 255};
  e.line = false;
  e.markers = true;
  PlotOptions o;
  o.log_x = o.log_y = true;
  o.title = "test";
  const std::vector<PlotSeries> series = {s, e};
  const std::string png = dir + "/p.png";
  WritePlotPng(png, series, o);
  const cv::Mat img = cv::imread(png);
  ASSERT_FALSE(img.empty());
  const PlotFrame f(series, o);
  ASSERT_TRUE(f.Valid());
  EXPECT_DOUBLE_EQ(f.x_min, 1);
  EXPECT_DOUBLE_EQ(f.x_max, 100);
  EXPECT_DOUBLE_EQ(f.y_min, 1);
  EXPECT_DOUBLE_EQ(f.y_max, 100);
  // The red line crosses the column at x = 30 on the row of y = 10 (the middle of the log axis).
  const int col = static_cast<int>(std::lround(f.PixelX(30)));
  const int row = static_cast<int>(std::lround(f.PixelY(10)));
  EXPECT_NEAR(row, (f.top + f.bottom) / 2.0, 1.0);
  bool red = false;
  for (int r = row - 2; r <= row + 2; ++r) {
    const cv::Vec3b p = img.at<cv::Vec3b>(r, col);  // BGR
    red |= p[2] > 200 && p[1] < 80 && p[0] < 80;
  }
  EXPECT_TRUE(red);
  // The blue marker at (3, 3).
  const cv::Vec3b m =
      img.at<cv::Vec3b>(static_cast<int>(std::lround(f.PixelY(3))), static_cast<int>(std::lround(f.PixelX(3))));
  EXPECT_GT(m[0], 200);
  EXPECT_LT(m[2], 80);
  EXPECT_THROW(WritePlotPng(dir + "/no/such/dir/p.png", series, o), std::exception);
}

}  // namespace
}  // namespace ssiu
