// `ssiu fuse` bad input that only the command sees: a unit file that does not describe the log.
#include <algorithm>
#include <filesystem>
#include <fstream>

#include "testing/testing.h"

namespace ssiu {
namespace {

using ::testing::HasSubstr;

TEST(FuseCli, UnitWithFewerGyrosThanTheLogIsRefused) {
  // A 3-gyro unit on a four-FOG log used to fuse g1..g3 and drop g4 without a word.
  const std::string d = testing::TempDir("fuse_cli_unit");
  std::ofstream(d + "/u3.json")
      << R"({"rate_hz": 100, "gyros": [{"axis": [1,0,0]}, {"axis": [0,1,0]}, {"axis": [0,0,1]}]})";
  std::ofstream(d + "/g4.csv") << "t_s,g1_dph,g2_dph,g3_dph,g4_dph\n0.01,1,2,3,4\n0.02,1,2,3,4\n0.03,1,2,3,4\n";
  std::ofstream(d + "/g3.csv") << "t_s,g1_dph,g2_dph,g3_dph,temp_c\n0.01,1,2,3,20\n0.02,1,2,3,20\n0.03,1,2,3,20\n";
  std::ofstream(d + "/st.csv") << "t_s,qw,qx,qy,qz\n0,1,0,0,0\n0.02,1,0,0,0\n";
  const std::string fuse = "fuse --st " + d + "/st.csv --json " + d + "/f.json --unit " + d + "/u3.json --gyro ";
  testing::SsiuResult r = testing::RunSsiu(fuse + d + "/g4.csv");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_THAT(r.output, HasSubstr("g4.csv: has g1_dph..g4_dph columns for 4 gyros but " + d + "/u3.json describes 3"));
  EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
  // The matching log (with an extra non-gyro column, kept and ignored) fuses.
  r = testing::RunSsiu(fuse + d + "/g3.csv");
  EXPECT_EQ(r.status, 0) << r.output;
  // And the four-FOG unit on a 3-column log names the count too.
  std::ofstream(d + "/u4.json")
      << R"({"gyros": [{"axis": [1,0,0]}, {"axis": [0,1,0]}, {"axis": [0,0,1]}, {"axis": [1,1,1]}]})";
  r = testing::RunSsiu("fuse --st " + d + "/st.csv --unit " + d + "/u4.json --gyro " + d + "/g3.csv");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_THAT(r.output, HasSubstr("for 3 gyros but " + d + "/u4.json describes 4"));
}

TEST(FuseCli, OutputsToAFullDeviceAreErrorsAndFilesAreWrittenWhole) {
  // `--out /dev/full` exited 0 with the data lost: a write error is exit 1 naming the file.
  const std::string d = testing::TempDir("fuse_cli_full");
  std::ofstream(d + "/g.csv") << "t_s,wx_dph,wy_dph,wz_dph\n0.01,1,2,3\n0.02,1,2,3\n0.03,1,2,3\n";
  std::ofstream(d + "/st.csv") << "t_s,qw,qx,qy,qz\n0,1,0,0,0\n0.02,1,0,0,0\n";
  const std::string fuse = "fuse --gyro " + d + "/g.csv --st " + d + "/st.csv ";
  if (std::ifstream("/dev/full").good()) {
    for (const std::string flag : {"--out", "--json"}) {
      const testing::SsiuResult r = testing::RunSsiu(fuse + flag + " /dev/full");
      EXPECT_EQ(r.status, 1) << flag << "\n" << r.output;
      EXPECT_THAT(r.output, HasSubstr("/dev/full")) << flag;
    }
  }
  // Into a regular file: complete, and nothing else left beside it (the temporary was renamed).
  const testing::SsiuResult r = testing::RunSsiu(fuse + "--out " + d + "/a.csv --json " + d + "/a.json");
  ASSERT_EQ(r.status, 0) << r.output;
  std::ifstream in(d + "/a.csv");
  std::string line;
  int lines = 0;
  while (std::getline(in, line)) ++lines;
  EXPECT_EQ(lines, 4);  // header + 3 samples
  int files = 0;
  for (const auto& e : std::filesystem::directory_iterator(d)) files += e.is_regular_file();
  EXPECT_EQ(files, 4);  // g.csv, st.csv, a.csv, a.json
}

}  // namespace
}  // namespace ssiu
