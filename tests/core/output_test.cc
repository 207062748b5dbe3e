// Atomic, checked outputs (issue 16, item 2): a writer that fails half-way leaves the old file intact,
// and a write error (a full disk, simulated by /dev/full) is an InputError naming the file.
#include "core/output.h"

#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/csv.h"
#include "core/error.h"
#include "core/image.h"
#include "core/json.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

std::string Slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

int FilesIn(const std::string& dir) {
  int n = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir)) n += e.is_regular_file();
  return n;
}

TEST(AtomicOutput, AWriterKilledHalfWayLeavesTheOldFileIntact) {
  const std::string d = testing::TempDir("atomic_output_killed");
  const std::string path = d + "/attitude.csv";
  WriteFileAtomic(path, std::string("t_s,qw\n0,1\n1,1\n"));
  ASSERT_EQ(Slurp(path), "t_s,qw\n0,1\n1,1\n");
  // The injected failure: the writer dies after half of its data (as a killed `fuse --out` did).
  EXPECT_THROW(WriteFileAtomic(path,
                               [](std::ostream& out) {
                                 out << "t_s,qw\n0,1\n";
                                 throw std::runtime_error("killed");
                               }),
               std::runtime_error);
  EXPECT_EQ(Slurp(path), "t_s,qw\n0,1\n1,1\n");
  EXPECT_EQ(FilesIn(d), 1);  // no temporary left behind
  // A complete write replaces it.
  WriteCsv(path, {"t_s", "qw"}, {{0, 1, 2}, {1, 1, 1}});
  EXPECT_EQ(Slurp(path), "t_s,qw\n0,1\n1,1\n2,1\n");
  EXPECT_EQ(FilesIn(d), 1);
}

TEST(AtomicOutput, WriteErrorsAreInputErrorsNamingTheFile) {
  if (!std::ifstream("/dev/full").good()) GTEST_SKIP() << "/dev/full is absent";
  std::vector<double> many(100000, 1.0);  // more than a stream buffer
  try {
    WriteCsv("/dev/full", {"t_s"}, {many});
    ADD_FAILURE() << "no error writing to /dev/full";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("/dev/full"));
  }
  EXPECT_THROW(WriteJsonFile("/dev/full", Json{{"a", 1}}), InputError);
  EXPECT_THROW(WriteFileAtomic("/dev/full", std::string("x")), InputError);
  // A directory that does not exist, and a directory as the target.
  const std::string d = testing::TempDir("atomic_output_errors");
  EXPECT_THROW(WriteFileAtomic(d + "/missing/f.json", std::string("{}")), InputError);
  EXPECT_THROW(WriteFileAtomic(d, std::string("{}")), InputError);
}

TEST(AtomicOutput, PngOutputsRefuseAnotherExtension) {
  const std::string d = testing::TempDir("atomic_output_png");
  EXPECT_THROW(WritePng8(d + "/out.xyz", 16, 16, std::vector<uint8_t>(256, 7)), InputError);
  WritePng8(d + "/out.png", 16, 16, std::vector<uint8_t>(256, 7));
  EXPECT_EQ(FilesIn(d), 1);
  EXPECT_EQ(Slurp(d + "/out.png").substr(1, 3), "PNG");
}

}  // namespace
}  // namespace ssiu
