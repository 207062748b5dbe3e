#include "core/csv.h"

#include <fstream>

#include "core/error.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

std::string Write(const std::string& dir, const std::string& name, const std::string& text) {
  const std::string p = dir + "/" + name;
  std::ofstream(p) << text;
  return p;
}

std::string ErrorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

TEST(Csv, ReadsColumnsAndKeepsUnknownOnes) {
  const std::string dir = testing::TempDir("csv");
  const auto p = Write(dir, "a.csv", "t_s,w_dph,note\n0,1.5,hello\n1,2.5,world\n");
  const CsvTable t = ReadCsv(p);
  EXPECT_EQ(t.rows(), 2u);
  EXPECT_DOUBLE_EQ(t.Column("w_dph")[1], 2.5);
  EXPECT_TRUE(t.Has("note"));
  EXPECT_THAT(ErrorOf([&] { t.Column("note"); }), ::testing::HasSubstr("column 'note'"));
}

TEST(Csv, BadInputNamesFileColumnAndRow) {
  const std::string dir = testing::TempDir("csv");
  const auto missing = Write(dir, "m.csv", "t_s,w_dph\n0,1\n");
  EXPECT_THAT(ErrorOf([&] { ReadCsv(missing).Column("temp_c"); }), ::testing::HasSubstr("m.csv: missing column 'temp_c'"));
  const auto nan = Write(dir, "n.csv", "t_s,w_dph\n0,1\n1,nan\n");
  EXPECT_THAT(ErrorOf([&] { ReadCsv(nan).Column("w_dph"); }), ::testing::HasSubstr("row 2, column 'w_dph'"));
  const auto unsorted = Write(dir, "u.csv", "t_s,w_dph\n0,1\n2,1\n1,1\n");
  EXPECT_THAT(ErrorOf([&] { ReadCsv(unsorted).CheckIncreasing("t_s"); }), ::testing::HasSubstr("not strictly increasing"));
  const auto empty = Write(dir, "e.csv", "");
  EXPECT_THAT(ErrorOf([&] { ReadCsv(empty); }), ::testing::HasSubstr("e.csv: empty file"));
  const auto ragged = Write(dir, "r.csv", "a,b\n1,2\n3\n");
  EXPECT_THAT(ErrorOf([&] { ReadCsv(ragged); }), ::testing::HasSubstr("row 2"));
}

TEST(Csv, WriteThenReadRoundTrips) {
  const std::string dir = testing::TempDir("csv");
  WriteCsv(dir + "/o.csv", {"t_s", "qw"}, {{0.0, 0.5}, {1.0, 0.25}});
  const CsvTable t = ReadCsv(dir + "/o.csv");
  EXPECT_DOUBLE_EQ(t.Column("qw")[1], 0.25);
}

}  // namespace
}  // namespace ssiu
