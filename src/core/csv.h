// CSV logs (../shared/docs/conventions.md): comma separated, one header line, names carry units.
// Unknown extra columns are kept and never an error; a requested column that is missing or holds a
// non-number / NaN is an InputError naming the file, the column and the row.
#pragma once

#include <string>
#include <vector>

namespace ssiu {

class CsvTable {
 public:
  std::string file;
  std::vector<std::string> header;

  size_t rows() const { return rows_; }
  bool Has(const std::string& name) const;
  // Column by name; InputError if missing or if any cell is not a finite decimal number.
  const std::vector<double>& Column(const std::string& name) const;
  // Throws InputError unless the column strictly increases.
  void CheckIncreasing(const std::string& name) const;

  // Used by ReadCsv and by code that builds tables in memory. first_bad_row: 1-based data row of the
  // first bad cell (-1 if none) and why it is bad (default: not a finite decimal number).
  void AddColumn(const std::string& name, std::vector<double> values, long first_bad_row = -1,
                 const std::string& why_bad = "");

 private:
  size_t rows_ = 0;
  std::vector<std::vector<double>> columns_;
  std::vector<long> first_bad_row_;  // 1-based data row of the first bad cell, -1 if none
  std::vector<std::string> why_bad_;
};

// Physical bounds of a column, by the unit its name carries (conventions: names carry units):
// `_dph` |rate| <= 3.6e6 deg/h (1000 deg/s, beyond any gyro's range), `_dps` |rate| <= 1000 deg/s,
// `temp_c` / `_c` in [-273.15, 1000] deg C, `_ut` |field| <= 1e6 uT (1 T). A cell outside is refused
// when its column is used, naming the row and column; other columns are unbounded. false if none.
bool PhysicalBound(const std::string& column, double* lo, double* hi, std::string* text);

// A CSV number: decimal, as in "-1.5e-3" (strtod alone also takes "0x10", "inf" and "nan"); false
// for anything else or a value that is not finite.
bool ParseDecimal(const std::string& text, double* value);

// Reads a CSV file; InputError for a missing/empty file, no header or ragged rows. A UTF-8 byte-order
// mark before the header (spreadsheet exports) is skipped.
CsvTable ReadCsv(const std::string& path);

// Writes columns of equal length with a header; `precision` significant digits.
void WriteCsv(const std::string& path, const std::vector<std::string>& header,
              const std::vector<std::vector<double>>& columns, int precision = 12);

}  // namespace ssiu
