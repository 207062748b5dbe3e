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

using testing::ErrorOf;

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
  EXPECT_THAT(ErrorOf([&] { ReadCsv(missing).Column("temp_c"); }),
              ::testing::HasSubstr("m.csv: missing column 'temp_c'"));
  const auto nan = Write(dir, "n.csv", "t_s,w_dph\n0,1\n1,nan\n");
  EXPECT_THAT(ErrorOf([&] { ReadCsv(nan).Column("w_dph"); }), ::testing::HasSubstr("row 2, column 'w_dph'"));
  const auto unsorted = Write(dir, "u.csv", "t_s,w_dph\n0,1\n2,1\n1,1\n");
  EXPECT_THAT(ErrorOf([&] { ReadCsv(unsorted).CheckIncreasing("t_s"); }),
              ::testing::HasSubstr("not strictly increasing"));
  const auto empty = Write(dir, "e.csv", "");
  EXPECT_THAT(ErrorOf([&] { ReadCsv(empty); }), ::testing::HasSubstr("e.csv: empty file"));
  const auto ragged = Write(dir, "r.csv", "a,b\n1,2\n3\n");
  EXPECT_THAT(ErrorOf([&] { ReadCsv(ragged); }), ::testing::HasSubstr("row 2"));
  // strtod reads "0x10" as 16: a CSV number is decimal, so it is refused like any non-number.
  const auto hex = Write(dir, "h.csv", "t_s,w_dph\n0,1\n1,0x10\n");
  EXPECT_THAT(ErrorOf([&] { ReadCsv(hex).Column("w_dph"); }),
              ::testing::HasSubstr("h.csv: row 2, column 'w_dph': not a finite decimal number"));
  const auto infinite = Write(dir, "i.csv", "t_s,w_dph\n0,-inf\n1,2\n");
  EXPECT_THAT(ErrorOf([&] { ReadCsv(infinite).Column("w_dph"); }), ::testing::HasSubstr("row 1, column 'w_dph'"));
}

TEST(Csv, ParseDecimalTakesDecimalNumbersOnly) {
  double v = 0;
  for (const char* ok : {"0", "-1.5", "+2.", ".5", "1e-3", "-7.25E+2", "3"}) EXPECT_TRUE(ParseDecimal(ok, &v)) << ok;
  EXPECT_TRUE(ParseDecimal("-7.25E+2", &v));
  EXPECT_DOUBLE_EQ(v, -725.0);
  for (const char* bad :
       {"", "0x10", "0X1p3", "nan", "inf", "infinity", "1e", "e5", "1.2.3", "1,5", " 1", "1 ", "--1", "1e999"}) {
    EXPECT_FALSE(ParseDecimal(bad, &v)) << bad;
  }
}

TEST(Csv, ByteOrderMarkBeforeTheHeaderIsSkipped) {
  // Spreadsheets write a UTF-8 BOM first; it used to make the first column "missing".
  const std::string dir = testing::TempDir("csv");
  const auto p = Write(dir, "bom.csv", "\xEF\xBB\xBFt_s,w_dph\n0,1.5\n1,2.5\n");
  const CsvTable t = ReadCsv(p);
  ASSERT_TRUE(t.Has("t_s"));
  EXPECT_DOUBLE_EQ(t.Column("t_s")[1], 1.0);
  t.CheckIncreasing("t_s");
  // Only at the very start: a BOM-only file is still empty.
  const auto only = Write(dir, "only.csv", "\xEF\xBB\xBF\n");
  EXPECT_THAT(ErrorOf([&] { ReadCsv(only); }), ::testing::HasSubstr("only.csv: empty file"));
}

TEST(Csv, WriteThenReadRoundTrips) {
  const std::string dir = testing::TempDir("csv");
  WriteCsv(dir + "/o.csv", {"t_s", "qw"}, {{0.0, 0.5}, {1.0, 0.25}});
  const CsvTable t = ReadCsv(dir + "/o.csv");
  EXPECT_DOUBLE_EQ(t.Column("qw")[1], 0.25);
}

}  // namespace
}  // namespace ssiu
