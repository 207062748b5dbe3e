#include "core/csv.h"

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <iomanip>
#include <sstream>

#include "core/error.h"
#include "core/output.h"

namespace ssiu {
namespace {

std::string Trim(const std::string& s) {
  const auto a = s.find_first_not_of(" \t\r\n");
  if (a == std::string::npos) return "";
  const auto b = s.find_last_not_of(" \t\r\n");
  return s.substr(a, b - a + 1);
}

std::vector<std::string> SplitComma(const std::string& line) {
  std::vector<std::string> out;
  std::string cell;
  std::istringstream ss(line);
  while (std::getline(ss, cell, ',')) out.push_back(Trim(cell));
  if (!line.empty() && line.back() == ',') out.push_back("");
  return out;
}

}  // namespace

bool ParseDecimal(const std::string& text, double* value) {
  if (text.empty() || text.find_first_not_of("0123456789+-.eE") != std::string::npos) return false;
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (end != text.c_str() + text.size() || !std::isfinite(v)) return false;
  *value = v;
  return true;
}

bool CsvTable::Has(const std::string& name) const {
  for (const auto& h : header) {
    if (h == name) return true;
  }
  return false;
}

const std::vector<double>& CsvTable::Column(const std::string& name) const {
  for (size_t i = 0; i < header.size(); ++i) {
    if (header[i] != name) continue;
    if (first_bad_row_[i] >= 0) {
      throw InputError(file, "row " + std::to_string(first_bad_row_[i]) + ", column '" + name +
                                 "': " + (why_bad_[i].empty() ? "not a finite decimal number" : why_bad_[i]));
    }
    return columns_[i];
  }
  throw InputError(file, "missing column '" + name + "'");
}

void CsvTable::CheckIncreasing(const std::string& name) const {
  const auto& c = Column(name);
  for (size_t i = 1; i < c.size(); ++i) {
    if (!(c[i] > c[i - 1])) {
      throw InputError(file, "column '" + name + "' is not strictly increasing at row " + std::to_string(i + 1));
    }
  }
}

void CsvTable::AddColumn(const std::string& name, std::vector<double> values, long first_bad_row,
                         const std::string& why_bad) {
  if (!columns_.empty() && values.size() != rows_) throw std::logic_error("CsvTable: ragged column " + name);
  rows_ = values.size();
  header.push_back(name);
  columns_.push_back(std::move(values));
  first_bad_row_.push_back(first_bad_row);
  why_bad_.push_back(why_bad);
}

bool PhysicalBound(const std::string& column, double* lo, double* hi, std::string* text) {
  auto ends = [&](const char* suffix) {
    const std::string x(suffix);
    return column.size() >= x.size() && column.compare(column.size() - x.size(), x.size(), x) == 0;
  };
  if (ends("_dph")) {
    *lo = -3.6e6, *hi = 3.6e6, *text = "|rate| <= 3.6e6 deg/h (1000 deg/s)";
  } else if (ends("_dps")) {
    *lo = -1000, *hi = 1000, *text = "|rate| <= 1000 deg/s";
  } else if (ends("_c")) {
    *lo = -273.15, *hi = 1000, *text = "-273.15 <= temperature <= 1000 deg C";
  } else if (ends("_ut")) {
    *lo = -1e6, *hi = 1e6, *text = "|field| <= 1e6 uT (1 T)";
  } else {
    return false;
  }
  return true;
}

CsvTable ReadCsv(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path, "cannot open file");
  std::string line;
  if (std::getline(in, line) && line.compare(0, 3, "\xEF\xBB\xBF") == 0) line.erase(0, 3);  // UTF-8 BOM
  if (!in || Trim(line).empty()) throw InputError(path, "empty file (no header line)");
  const std::vector<std::string> names = SplitComma(line);
  for (const auto& n : names) {
    if (n.empty()) throw InputError(path, "header has an empty column name");
  }
  std::vector<std::vector<double>> cols(names.size());
  std::vector<long> bad(names.size(), -1);
  std::vector<std::string> why(names.size());
  struct Bound {
    bool on = false;
    double lo = 0, hi = 0;
    std::string text;
  };
  std::vector<Bound> bounds(names.size());
  for (size_t i = 0; i < names.size(); ++i)
    bounds[i].on = PhysicalBound(names[i], &bounds[i].lo, &bounds[i].hi, &bounds[i].text);
  long row = 0;
  while (std::getline(in, line)) {
    if (Trim(line).empty()) continue;
    ++row;
    const auto cells = SplitComma(line);
    if (cells.size() != names.size()) {
      throw InputError(path, "row " + std::to_string(row) + " has " + std::to_string(cells.size()) +
                                 " fields, header has " + std::to_string(names.size()));
    }
    for (size_t i = 0; i < cells.size(); ++i) {
      double v = 0;
      const bool ok = ParseDecimal(cells[i], &v);
      if (!ok && bad[i] < 0) bad[i] = row;
      if (ok && bounds[i].on && !(v >= bounds[i].lo && v <= bounds[i].hi) && bad[i] < 0) {
        bad[i] = row;
        why[i] = cells[i] + " is physically impossible (" + bounds[i].text + ")";
      }
      cols[i].push_back(ok ? v : std::nan(""));
    }
  }
  if (row == 0) throw InputError(path, "no data rows");
  CsvTable t;
  t.file = path;
  for (size_t i = 0; i < names.size(); ++i) t.AddColumn(names[i], std::move(cols[i]), bad[i], why[i]);
  return t;
}

void WriteCsv(const std::string& path, const std::vector<std::string>& header,
              const std::vector<std::vector<double>>& columns, int precision) {
  WriteFileAtomic(path, [&](std::ostream& out) {
    for (size_t i = 0; i < header.size(); ++i) out << (i ? "," : "") << header[i];
    out << "\n" << std::setprecision(precision);
    const size_t n = columns.empty() ? 0 : columns[0].size();
    for (size_t r = 0; r < n; ++r) {
      for (size_t c = 0; c < columns.size(); ++c) out << (c ? "," : "") << columns[c][r];
      out << "\n";
    }
  });
}

}  // namespace ssiu
