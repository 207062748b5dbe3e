#include "calibration/allan_io.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "core/csv.h"
#include "core/error.h"
#include "core/types.h"
#include "plot/plot.h"

namespace ssiu {
namespace {

bool EndsWith(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

std::string Trim(const std::string& s) {
  const auto a = s.find_first_not_of(" \t\r\n\"");
  if (a == std::string::npos) return "";
  const auto b = s.find_last_not_of(" \t\r\n\"");
  return s.substr(a, b - a + 1);
}

std::string Lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

// Comma separated if the line has a comma, else whitespace separated.
std::vector<std::string> SplitCells(const std::string& line) {
  std::vector<std::string> out;
  if (line.find(',') != std::string::npos) {
    std::string cell;
    std::istringstream ss(line);
    while (std::getline(ss, cell, ',')) out.push_back(Trim(cell));
    if (!line.empty() && line.back() == ',') out.push_back("");
  } else {
    std::istringstream ss(line);
    std::string cell;
    while (ss >> cell) out.push_back(cell);
  }
  return out;
}

bool ParseNumber(const std::string& s, double* v) {
  // Decimal only, as in core/csv.h (strtod would read "0x10" as 16); "nan" passes here and is
  // refused where a value must be finite.
  if (s.empty() || s.find_first_of("xX") != std::string::npos) return false;
  char* end = nullptr;
  *v = std::strtod(s.c_str(), &end);
  return end && *end == '\0';
}

// "key=value" in a comment line, e.g. "freq_hz=400.0 n=5760000".
bool CommentValue(const std::string& line, const std::string& key, double* v) {
  size_t pos = 0;
  while ((pos = line.find(key + "=", pos)) != std::string::npos) {
    if (pos == 0 || line[pos - 1] == ' ' || line[pos - 1] == ';' || line[pos - 1] == ',') {
      const size_t start = pos + key.size() + 1;
      const size_t end = line.find_first_of(" ;,\t", start);
      return ParseNumber(line.substr(start, end == std::string::npos ? std::string::npos : end - start), v);
    }
    ++pos;
  }
  return false;
}

struct TextTable {
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;
  std::map<std::string, double> comment_values;
  bool has_header = true;
};

TextTable ReadTextTable(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path, "cannot open file");
  TextTable t;
  std::string line;
  bool first = true;
  while (std::getline(in, line)) {
    const std::string s = Trim(line);
    if (s.empty()) continue;
    if (s[0] == '#') {
      for (const char* key : {"freq_hz", "n"}) {
        double v;
        if (CommentValue(s, key, &v)) t.comment_values[key] = v;
      }
      continue;
    }
    auto cells = SplitCells(s);
    if (first) {
      first = false;
      double v;
      t.has_header = !std::all_of(cells.begin(), cells.end(), [&](const std::string& c) { return ParseNumber(c, &v); });
      if (t.has_header) {
        t.header = cells;
        continue;
      }
      for (size_t i = 0; i < cells.size(); ++i) t.header.push_back("column" + std::to_string(i + 1));
    }
    if (cells.size() != t.header.size()) {
      throw InputError(path, "row " + std::to_string(t.rows.size() + 1) + " has " + std::to_string(cells.size()) +
                                 " fields, header has " + std::to_string(t.header.size()));
    }
    t.rows.push_back(std::move(cells));
  }
  if (t.header.empty()) throw InputError(path, "empty file (no header line)");
  if (t.rows.empty()) throw InputError(path, "no data rows");
  return t;
}

int ColumnIndex(const TextTable& t, const std::string& name) {
  for (size_t i = 0; i < t.header.size(); ++i) {
    if (t.header[i] == name) return static_cast<int>(i);
  }
  return -1;
}

std::vector<double> NumericColumn(const TextTable& t, int col, const std::vector<size_t>& rows,
                                  const std::string& file) {
  std::vector<double> out;
  out.reserve(rows.size());
  for (size_t r : rows) {
    double v;
    if (!ParseNumber(t.rows[r][col], &v) || !std::isfinite(v)) {
      throw InputError(file, "row " + std::to_string(r + 1) + ", column '" + t.header[col] + "': not a finite number");
    }
    out.push_back(v);
  }
  return out;
}

NoiseTerm Scaled(const NoiseTerm& t, double k) {
  NoiseTerm s = t;
  s.value *= k;
  s.sigma *= k;
  return s;
}

Json TermJson(const NoiseTerm& t, const std::string& unit) {
  Json j;
  j["value"] = t.value;
  j["sigma"] = t.sigma;
  j["unit"] = unit;
  j["tau_range_s"] = t.tau_max_s > 0 ? Json::array({t.tau_min_s, t.tau_max_s}) : Json::array();
  j["significant"] = t.significant;
  j["max_variance_fraction"] = t.max_fraction;
  return j;
}

}  // namespace

const char* RateUnitName(RateUnit unit) {
  switch (unit) {
    case RateUnit::kRadPerS:
      return "rad/s";
    case RateUnit::kDegPerS:
      return "deg/s";
    case RateUnit::kDegPerH:
      return "deg/h";
  }
  return "?";
}

double RateUnitToRadPerS(RateUnit unit) {
  switch (unit) {
    case RateUnit::kRadPerS:
      return 1.0;
    case RateUnit::kDegPerS:
      return kPi / 180.0;
    case RateUnit::kDegPerH:
      return kPi / 180.0 / 3600.0;
  }
  return 1.0;
}

bool RateUnitFromName(const std::string& column, RateUnit* unit) {
  const std::string c = Lower(column);
  if (EndsWith(c, "_dph") || EndsWith(c, "_deg_h") || EndsWith(c, "_deg_per_h"))
    *unit = RateUnit::kDegPerH;
  else if (EndsWith(c, "_dps") || EndsWith(c, "_deg_s") || EndsWith(c, "_deg_per_s"))
    *unit = RateUnit::kDegPerS;
  else if (EndsWith(c, "_rps") || EndsWith(c, "_rad_s") || EndsWith(c, "_rad_per_s"))
    *unit = RateUnit::kRadPerS;
  else
    return false;
  return true;
}

RateUnit ParseRateUnit(const std::string& text, const std::string& file) {
  const std::string t = Lower(text);
  if (t == "rad/s" || t == "rps") return RateUnit::kRadPerS;
  if (t == "deg/s" || t == "dps") return RateUnit::kDegPerS;
  if (t == "deg/h" || t == "dph") return RateUnit::kDegPerH;
  throw InputError(file, "unknown rate unit '" + text + "' (use rad/s, deg/s or deg/h)");
}

RateLog ReadRateLog(const std::string& path, const std::string& column, const std::string& unit, double fs) {
  const CsvTable t = ReadCsv(path);
  RateLog log;
  log.file = path;
  log.column = column;
  if (!unit.empty()) {
    log.unit = ParseRateUnit(unit, path);
  } else if (!RateUnitFromName(column, &log.unit)) {
    throw InputError(path, "column '" + column + "': rate unit not in its name (_dph, _dps, _rps): give --unit");
  }
  const std::vector<double>& r = t.Column(column);
  if (fs > 0) {
    log.sample_rate_hz = fs;
  } else {
    if (!t.Has("t_s")) throw InputError(path, "missing column 't_s' (or give --sample-rate-hz)");
    t.CheckIncreasing("t_s");
    const std::vector<double>& ts = t.Column("t_s");
    if (ts.size() < 2) throw InputError(path, "column 't_s': too few samples");
    std::vector<double> dt(ts.size() - 1);
    for (size_t i = 1; i < ts.size(); ++i) dt[i - 1] = ts[i] - ts[i - 1];
    std::vector<double> sorted = dt;
    std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
    const double median = sorted[sorted.size() / 2];
    for (size_t i = 0; i < dt.size(); ++i) {
      // The Allan variance needs equally spaced samples: a gap would be silently wrong.
      if (dt[i] > 1.5 * median || dt[i] < 0.5 * median) {
        throw InputError(path, "column 't_s': irregular sampling at row " + std::to_string(i + 2) + " (step " +
                                   std::to_string(dt[i]) + " s, median " + std::to_string(median) + " s)");
      }
    }
    log.sample_rate_hz = (ts.size() - 1) / (ts.back() - ts.front());
  }
  const double k = RateUnitToRadPerS(log.unit);
  log.rate_rad_s.reserve(r.size());
  for (double v : r) log.rate_rad_s.push_back(v * k);
  return log;
}

namespace {

// The options' values behind the curve: a negative or non-finite length/rate was silently ignored
// (the file's own values or none used instead), whichever command passed it.
void CheckCurveFileOptions(const std::string& path, const CurveFileOptions& o) {
  if (!(o.confidence > 0 && o.confidence < 1)) throw InputError(path, "confidence must be in (0, 1)");
  auto non_negative = [&](double v, const char* field) {
    if (!(std::isfinite(v) && v >= 0)) throw InputError(path, std::string(field) + " must be a finite number >= 0");
  };
  non_negative(o.sample_rate_hz, "sample rate (--sample-rate-hz)");
  non_negative(o.n, "sample count (--n)");
  non_negative(o.duration_s, "duration (--duration-s)");
}

// The columns read from a curve file: the table rows used, tau (s), ADEV (file unit), and the
// per-point edf or SMAC-Group rel_error when the file has them.
struct CurveColumns {
  std::vector<size_t> rows;
  std::vector<double> tau, adev, edf, rel;
};

// imu_utils layout: tau and ADEV columns, or one ADEV column here and the taus in o.tau_file.
CurveColumns ReadHeaderlessColumns(const TextTable& t, const std::string& path, const CurveFileOptions& o,
                                   CurveFile* out) {
  CurveColumns cc;
  if (t.header.size() == 2 && o.tau_file.empty()) {
    for (size_t r = 0; r < t.rows.size(); ++r) cc.rows.push_back(r);
    cc.tau = NumericColumn(t, 0, cc.rows, path);
    cc.adev = NumericColumn(t, 1, cc.rows, path);
  } else if (t.header.size() == 1) {
    if (o.tau_file.empty()) throw InputError(path, "header-less one-column ADEV file: give --tau-file");
    const TextTable tt = ReadTextTable(o.tau_file);
    if (tt.has_header || tt.header.size() != 1) throw InputError(o.tau_file, "expected one column of taus in seconds");
    if (tt.rows.size() != t.rows.size()) {
      throw InputError(o.tau_file, std::to_string(tt.rows.size()) + " taus for " + std::to_string(t.rows.size()) +
                                       " ADEV values in " + path);
    }
    for (size_t r = 0; r < t.rows.size(); ++r) cc.rows.push_back(r);
    cc.tau = NumericColumn(tt, 0, cc.rows, o.tau_file);
    cc.adev = NumericColumn(t, 0, cc.rows, path);
  } else {
    throw InputError(path, "header-less file must have one (ADEV, with --tau-file) or two (tau, ADEV) columns");
  }
  out->tau_column = "column1";
  out->adev_column = t.header.size() == 2 ? "column2" : "column1";
  return cc;
}

// The channel column (one named "channel", else the first non-numeric column; -1 if none), the
// channels it holds into out->channels and the one to read into out->channel.
int SelectChannel(const TextTable& t, const std::string& path, const CurveFileOptions& o, CurveFile* out) {
  int ch = ColumnIndex(t, "channel");
  if (ch < 0) {
    for (size_t c = 0; c < t.header.size() && ch < 0; ++c) {
      double v;
      if (!ParseNumber(t.rows[0][c], &v)) ch = static_cast<int>(c);
    }
  }
  if (ch >= 0) {
    std::set<std::string> seen;
    for (const auto& r : t.rows) {
      if (seen.insert(r[ch]).second) out->channels.push_back(r[ch]);
    }
  }
  if (!o.channel.empty()) {
    if (ch < 0) throw InputError(path, "no channel column, but --channel '" + o.channel + "' was given");
    out->channel = o.channel;
  } else if (out->channels.size() == 1) {
    out->channel = out->channels[0];
  } else if (out->channels.size() > 1) {
    std::string list;
    for (const auto& c : out->channels) list += (list.empty() ? "" : ", ") + c;
    throw InputError(path, "column '" + t.header[ch] + "' holds several channels (" + list + "): give --channel");
  }
  return ch;
}

// The column given (which must exist), else the first of `names` present.
std::string PickColumn(const TextTable& t, const std::string& path, const std::string& given,
                       const std::vector<std::string>& names, const char* what) {
  if (!given.empty()) {
    if (ColumnIndex(t, given) < 0) throw InputError(path, "missing column '" + given + "'");
    return given;
  }
  for (const auto& n : names) {
    if (ColumnIndex(t, n) >= 0) return n;
  }
  throw InputError(path, std::string("no ") + what + " column found: give --" + what + "-column");
}

// ADEV column candidates: adev* (not its bounds or error), then avar* (square-rooted when read).
std::vector<std::string> AdevColumnNames(const TextTable& t) {
  std::vector<std::string> adev_names;
  for (const auto& h : t.header) {
    const std::string l = Lower(h);
    if (l.rfind("adev", 0) == 0 && l.find("lci") == std::string::npos && l.find("uci") == std::string::npos &&
        l.find("_lo") == std::string::npos && l.find("_hi") == std::string::npos &&
        l.find("err") == std::string::npos) {
      adev_names.push_back(h);
    }
  }
  for (const auto& h : t.header) {
    if (Lower(h).rfind("avar", 0) == 0) adev_names.push_back(h);
  }
  return adev_names;
}

// A CSV with a header: the channel's rows, the tau and ADEV columns (given or found), edf or rel_error.
CurveColumns ReadHeaderedColumns(const TextTable& t, const std::string& path, const CurveFileOptions& o,
                                 CurveFile* out) {
  CurveColumns cc;
  const int ch = SelectChannel(t, path, o, out);
  for (size_t r = 0; r < t.rows.size(); ++r) {
    if (ch < 0 || t.rows[r][ch] == out->channel) cc.rows.push_back(r);
  }
  if (cc.rows.empty()) throw InputError(path, "no rows of channel '" + o.channel + "'");
  out->tau_column = PickColumn(t, path, o.tau_column, {"tau_s", "tau", "tau_sec", "averaging_time_s"}, "tau");
  out->adev_column = PickColumn(t, path, o.adev_column, AdevColumnNames(t), "adev");
  cc.tau = NumericColumn(t, ColumnIndex(t, out->tau_column), cc.rows, path);
  cc.adev = NumericColumn(t, ColumnIndex(t, out->adev_column), cc.rows, path);
  if (Lower(out->adev_column).rfind("avar", 0) == 0) {
    for (double& v : cc.adev) {
      if (v < 0) throw InputError(path, "column '" + out->adev_column + "': negative Allan variance");
      v = std::sqrt(v);
    }
  }
  if (ColumnIndex(t, "edf") >= 0)
    cc.edf = NumericColumn(t, ColumnIndex(t, "edf"), cc.rows, path);
  else if (ColumnIndex(t, "rel_error") >= 0)
    cc.rel = NumericColumn(t, ColumnIndex(t, "rel_error"), cc.rows, path);
  return cc;
}

// At least three points, tau positive and strictly increasing, ADEV non-negative.
void CheckCurvePoints(const CurveColumns& cc, const std::string& path, const CurveFile& out) {
  const auto& tau = cc.tau;
  if (tau.size() < 3) throw InputError(path, "too few Allan points (" + std::to_string(tau.size()) + ")");
  for (size_t i = 0; i < tau.size(); ++i) {
    if (!(tau[i] > 0)) {
      throw InputError(path,
                       "column '" + out.tau_column + "': tau must be > 0 (row " + std::to_string(cc.rows[i] + 1) + ")");
    }
    if (i > 0 && !(tau[i] > tau[i - 1])) {
      throw InputError(
          path, "column '" + out.tau_column + "' is not strictly increasing at row " + std::to_string(cc.rows[i] + 1));
    }
    if (!(cc.adev[i] >= 0)) {
      throw InputError(path,
                       "column '" + out.adev_column + "': negative value at row " + std::to_string(cc.rows[i] + 1));
    }
  }
}

// Degrees of freedom of each point into c->edf: from the file (edf, else rel_error), else the formulas
// when the sample rate fs and count n are known, else assumed equal.
void SetCurveEdf(const CurveColumns& cc, double fs, double n, AllanCurve* c) {
  if (!cc.edf.empty()) {
    c->edf = cc.edf;
    c->edf_source = "file";
  } else if (!cc.rel.empty()) {
    // SMAC-Group's rel_error is 1/sqrt(2 (N/m - 1)), the relative error of ADEV: edf = 1 / (2 rel^2).
    for (double r : cc.rel) c->edf.push_back(r > 0 ? 1 / (2 * r * r) : 1.0);
    c->edf_source = "rel_error";
  } else if (fs > 0 && n > 0) {
    for (size_t i = 0; i < cc.tau.size(); ++i) {
      const double m = std::max(1.0, std::round(cc.tau[i] * fs));
      c->edf.push_back(2 * m <= n + 1 ? ConservativeAvarEdf(c->noise[i], n + 1, m) : 1.0);
    }
    c->edf_source = "formula";
  } else {
    c->edf.assign(cc.tau.size(), 100.0);
    c->edf_source = "assumed";
  }
  for (double& e : c->edf) e = std::max(e, 1.0);
}

}  // namespace

CurveFile ReadAllanCurveFile(const std::string& path, const CurveFileOptions& o) {
  CheckCurveFileOptions(path, o);
  const TextTable t = ReadTextTable(path);
  CurveFile out;
  out.file = path;
  const CurveColumns cc =
      t.has_header ? ReadHeaderedColumns(t, path, o, &out) : ReadHeaderlessColumns(t, path, o, &out);
  // Unit.
  if (!o.unit.empty()) {
    out.unit = ParseRateUnit(o.unit, path);
  } else if (!RateUnitFromName(out.adev_column, &out.unit)) {
    throw InputError(path, "column '" + out.adev_column +
                               "': rate unit not in its name (e.g. adev_dph): give --unit rad/s, deg/s or deg/h");
  }
  CheckCurvePoints(cc, path, out);
  AllanCurve& c = out.curve;
  const double k = RateUnitToRadPerS(out.unit);
  c.tau_s = cc.tau;
  for (double v : cc.adev) c.adev.push_back(v * k);
  c.noise = IdentifyNoiseBySlope(c.tau_s, c.adev);
  // The sample rate and length behind the curve: the options', else the file's comment values; a
  // duration sets the length (at the rate of the first tau when no rate is known).
  double fs = o.sample_rate_hz > 0                ? o.sample_rate_hz
              : t.comment_values.count("freq_hz") ? t.comment_values.at("freq_hz")
                                                  : 0;
  double n = o.n > 0 ? o.n : t.comment_values.count("n") ? t.comment_values.at("n") : 0;
  if (o.duration_s > 0) {
    if (fs <= 0) fs = 1 / cc.tau.front();
    n = o.duration_s * fs;
  }
  c.sample_rate_hz = fs;
  c.n = n > 0 ? static_cast<size_t>(n) : 0;
  SetCurveEdf(cc, fs, n, &c);
  SetConfidenceIntervals(&c, o.confidence);
  return out;
}

GyroNoiseTerms ToGyroUnits(const NoiseFit& f) {
  // Q [rad] -> arcsec; N [rad/sqrt(s)] -> deg/sqrt(h); B [rad/s] -> deg/h; K [rad/s/sqrt(s)] ->
  // deg/h/sqrt(h); R [rad/s^2] -> deg/h^2.
  GyroNoiseTerms g;
  g.quantization_arcsec = Scaled(f.quantization, kRadToArcsec);
  g.arw_deg_per_sqrt_h = Scaled(f.arw, kRadToDeg * 60.0);
  g.bias_instability_dph = Scaled(f.bias_instability, kRadSToDph);
  g.rrw_deg_per_h_per_sqrt_h = Scaled(f.rrw, kRadSToDph * 60.0);
  g.rate_ramp_deg_per_h2 = Scaled(f.rate_ramp, kRadSToDph * 3600.0);
  // Bias instability read from the curve's floor (IEEE 952 Annex C: B = floor / 0.664), as datasheets
  // quote it; an upper bound when random walk or ramp rise before a flat region appears.
  const double k_floor = kRadSToDph / std::sqrt(2 * std::log(2.0) / kPi);
  NoiseTerm& fl = g.bias_instability_floor_dph;
  fl.value = f.adev_min * k_floor;
  fl.sigma = f.adev_min_sigma * k_floor;
  fl.tau_min_s = fl.tau_max_s = f.tau_at_min_s;
  fl.significant = fl.value > 2 * fl.sigma;
  return g;
}

Json AllanReportJson(const AllanCurve& c, const NoiseFit& fit, const Json& provenance, double confidence) {
  Json j = provenance.is_object() ? provenance : Json::object();
  auto dph = [&](const std::vector<double>& v) {
    std::vector<double> out;
    out.reserve(v.size());
    for (double x : v) out.push_back(x * kRadSToDph);
    return out;
  };
  j["sample_rate_hz"] = c.sample_rate_hz;
  j["n"] = c.n;
  j["adev_unit"] = "deg/h";
  j["confidence"] = confidence;
  j["edf_source"] = c.edf_source;
  j["tau_s"] = c.tau_s;
  j["adev"] = dph(c.adev);
  j["adev_lo"] = dph(c.adev_lo);
  j["adev_hi"] = dph(c.adev_hi);
  j["edf"] = c.edf;
  std::vector<std::string> noise;
  for (AllanNoise n : c.noise) noise.push_back(AllanNoiseName(n));
  j["noise"] = noise;
  j["model_adev"] = dph(fit.model_adev);
  Json f;
  f["status"] = FitStatusName(fit.status);
  f["message"] = fit.message;
  f["chi2_per_dof"] = fit.chi2_per_dof;
  f["points_used"] = fit.points_used;
  f["adev_min_dph"] = fit.adev_min * kRadSToDph;
  f["tau_at_min_s"] = fit.tau_at_min_s;
  j["fit"] = f;
  const GyroNoiseTerms g = ToGyroUnits(fit);
  Json t;
  t["quantization_arcsec"] = TermJson(g.quantization_arcsec, "arcsec");
  t["arw_deg_per_sqrt_h"] = TermJson(g.arw_deg_per_sqrt_h, "deg/sqrt(h)");
  t["bias_instability_dph"] = TermJson(g.bias_instability_dph, "deg/h");
  t["rrw_deg_per_h_per_sqrt_h"] = TermJson(g.rrw_deg_per_h_per_sqrt_h, "deg/h/sqrt(h)");
  t["rate_ramp_deg_per_h2"] = TermJson(g.rate_ramp_deg_per_h2, "deg/h^2");
  t["bias_instability_floor_dph"] = TermJson(g.bias_instability_floor_dph, "deg/h");
  t["bias_instability_floor_dph"]["upper_bound"] = fit.adev_min_is_upper_bound;
  j["terms"] = t;
  return j;
}

void WriteAllanPlot(const std::string& path, const AllanCurve& c, const NoiseFit& fit, const std::string& title) {
  std::vector<PlotSeries> series;
  PlotSeries data;
  data.label = "overlapping ADEV";
  data.x = c.tau_s;
  for (size_t i = 0; i < c.adev.size(); ++i) {
    data.y.push_back(c.adev[i] * kRadSToDph);
    if (c.adev_lo.size() == c.adev.size() && c.adev_hi.size() == c.adev.size()) {
      data.y_lo.push_back(c.adev_lo[i] * kRadSToDph);
      data.y_hi.push_back(c.adev_hi[i] * kRadSToDph);
    }
  }
  data.color = {20, 60, 200};
  data.line = false;
  data.markers = true;
  series.push_back(data);
  if (fit.status == FitStatus::kFitted && !c.tau_s.empty()) {
    // The model and each fitted term on a fine grid over the curve's tau range.
    std::vector<double> grid;
    const double t0 = c.tau_s.front(), t1 = c.tau_s.back();
    for (int i = 0; i <= 200; ++i) grid.push_back(t0 * std::pow(t1 / t0, i / 200.0));
    PlotSeries model;
    model.label = "fitted model";
    model.color = {200, 30, 30};
    model.x = grid;
    for (double t : grid) model.y.push_back(fit.ModelAdev(t) * kRadSToDph);
    series.push_back(model);
    struct Part {
      const NoiseTerm* term;
      const char* name;
      PlotColor color;
      int j;
    };
    const Part parts[] = {{&fit.quantization, "quantization", {150, 0, 150}, 0},
                          {&fit.arw, "angle random walk", {0, 140, 0}, 1},
                          {&fit.bias_instability, "bias instability", {230, 140, 0}, 2},
                          {&fit.rrw, "rate random walk", {0, 150, 170}, 3},
                          {&fit.rate_ramp, "rate ramp", {110, 80, 40}, 4}};
    for (const Part& p : parts) {
      if (p.term->value <= 0) continue;
      PlotSeries s;
      s.label = p.name;
      s.color = p.color;
      s.dashed = true;
      s.thickness_px = 1;
      s.x = grid;
      const double v = p.term->value;
      for (double t : grid) {
        const double avar = p.j == 0   ? 3 * v * v / (t * t)
                            : p.j == 1 ? v * v / t
                            : p.j == 2 ? 2 * std::log(2.0) / kPi * v * v
                            : p.j == 3 ? v * v * t / 3
                                       : v * v * t * t / 2;
        s.y.push_back(std::sqrt(avar) * kRadSToDph);
      }
      series.push_back(s);
    }
  }
  PlotOptions o;
  o.log_x = o.log_y = true;
  o.title = title;
  o.x_label = "tau [s]";
  o.y_label = "Allan deviation [deg/h]";
  o.legend_bottom_left = true;
  // Keep the term lines from stretching the axes far below the data.
  double lo = 1e300;
  for (double v : data.y) {
    if (v > 0) lo = std::min(lo, v);
  }
  for (size_t k = 1; k < series.size(); ++k) {
    for (double& v : series[k].y) {
      if (v < lo / 30) v = std::nan("");
    }
  }
  WritePlotPng(path, series, o);
}

}  // namespace ssiu
