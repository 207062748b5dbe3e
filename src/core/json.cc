#include "core/json.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <set>
#include <sstream>

#include "core/error.h"
#include "core/output.h"

namespace ssiu {
namespace {

// Parses with nlohmann's callback, which sees every key before the object stores it (and keeps only
// the last of two equal keys): one set of keys per open object.
Json ParseStrict(std::istream& in, const std::string& file) {
  std::vector<std::set<std::string>> open_objects;
  std::string duplicate;
  const Json::parser_callback_t cb = [&](int, Json::parse_event_t event, Json& parsed) {
    switch (event) {
      case Json::parse_event_t::object_start:
        open_objects.emplace_back();
        break;
      case Json::parse_event_t::object_end:
        if (!open_objects.empty()) open_objects.pop_back();
        break;
      case Json::parse_event_t::key: {
        const std::string key = parsed.get<std::string>();
        if (!open_objects.empty() && !open_objects.back().insert(key).second && duplicate.empty()) duplicate = key;
        break;
      }
      default:
        break;
    }
    return true;
  };
  Json j;
  try {
    j = Json::parse(in, cb, true, /*ignore_comments=*/true);
  } catch (const Json::exception& e) {  // parse_error, and out_of_range for a number overflow (1e999)
    throw InputError(file, std::string("not valid JSON (") + e.what() + ")");
  } catch (const std::ios_base::failure&) {
    throw InputError(file, "read error");
  }
  if (!duplicate.empty()) throw InputError(file, "duplicate key '" + duplicate + "'");
  return j;
}

// Optimal string alignment distance (Levenshtein plus adjacent transpositions, each costing 1).
size_t EditDistance(const std::string& a, const std::string& b) {
  const size_t n = a.size(), m = b.size();
  std::vector<std::vector<size_t>> d(n + 1, std::vector<size_t>(m + 1));
  for (size_t i = 0; i <= n; ++i) d[i][0] = i;
  for (size_t k = 0; k <= m; ++k) d[0][k] = k;
  for (size_t i = 1; i <= n; ++i) {
    for (size_t k = 1; k <= m; ++k) {
      const size_t cost = a[i - 1] == b[k - 1] ? 0 : 1;
      d[i][k] = std::min({d[i - 1][k] + 1, d[i][k - 1] + 1, d[i - 1][k - 1] + cost});
      if (i > 1 && k > 1 && a[i - 1] == b[k - 2] && a[i - 2] == b[k - 1])
        d[i][k] = std::min(d[i][k], d[i - 2][k - 2] + 1);
    }
  }
  return d[n][m];
}

const char* TypeName(const Json& v) {
  if (v.is_boolean()) return "true/false";
  if (v.is_string()) return "a string";
  if (v.is_array()) return "an array";
  if (v.is_object()) return "an object";
  if (v.is_null()) return "null";
  return "a number";
}

std::string Field(const std::string& key) { return "field '" + key + "'"; }

}  // namespace

Json ParseJsonStrict(const std::string& text, const std::string& file) {
  std::istringstream in(text);
  return ParseStrict(in, file);
}

Json ReadJsonFile(const std::string& path) {
  // A directory opens as a stream on Linux and then fails inside the parser with an I/O exception.
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) throw InputError(path, "is a directory, not a JSON file");
  std::ifstream in(path);
  if (!in) throw InputError(path, "cannot open file");
  return ParseStrict(in, path);
}

void WriteJsonFile(const std::string& path, const Json& j) {
  WriteFileAtomic(path, [&](std::ostream& out) { out << j.dump(2) << "\n"; });
}

std::string NearestKey(const std::string& key, const std::vector<std::string>& allowed) {
  std::string best;
  size_t best_d = std::max<size_t>(1, key.size() / 3) + 1;
  for (const auto& a : allowed) {
    const size_t d = EditDistance(key, a);
    if (d < best_d) best_d = d, best = a;
  }
  return best;
}

void CheckKeys(const Json& j, const std::vector<std::string>& allowed, const std::string& file) {
  if (!j.is_object()) throw InputError(file, "must be a JSON object");
  for (auto it = j.begin(); it != j.end(); ++it) {
    if (std::find(allowed.begin(), allowed.end(), it.key()) != allowed.end()) continue;
    const std::string near = NearestKey(it.key(), allowed);
    std::string hint;
    if (!near.empty()) {
      hint = " (did you mean '" + near + "'?)";
    } else {
      hint = " (allowed:";
      for (size_t i = 0; i < allowed.size(); ++i) hint += (i ? ", " : " ") + allowed[i];
      hint += ")";
    }
    throw InputError(file, "unknown key '" + it.key() + "'" + hint);
  }
}

double JsonNumber(const Json& j, const std::string& key, const std::string& file) {
  if (!j.is_object() || !j.contains(key)) throw InputError(file, "missing " + Field(key));
  const Json& v = j.at(key);
  if (!v.is_number()) throw InputError(file, Field(key) + " is not a number (it is " + TypeName(v) + ")");
  const double d = v.get<double>();
  if (!std::isfinite(d)) throw InputError(file, Field(key) + " is not finite");
  return d;
}

double JsonNumberOr(const Json& j, const std::string& key, double fallback, const std::string& file) {
  if (!j.is_object() || !j.contains(key) || j.at(key).is_null()) return fallback;
  return JsonNumber(j, key, file);
}

int64_t JsonInt(const Json& j, const std::string& key, int64_t lo, int64_t hi, const std::string& file) {
  const double d = JsonNumber(j, key, file);
  // Compared as doubles before any conversion; lo and hi are far inside +-2^53 in practice.
  if (!(d >= static_cast<double>(lo) && d <= static_cast<double>(hi)) || d != std::floor(d)) {
    throw InputError(
        file, Field(key) + " must be a whole number in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
  }
  return static_cast<int64_t>(d);
}

int64_t JsonIntOr(const Json& j, const std::string& key, int64_t fallback, int64_t lo, int64_t hi,
                  const std::string& file) {
  if (!j.is_object() || !j.contains(key) || j.at(key).is_null()) return fallback;
  return JsonInt(j, key, lo, hi, file);
}

bool JsonBoolOr(const Json& j, const std::string& key, bool fallback, const std::string& file) {
  if (!j.is_object() || !j.contains(key) || j.at(key).is_null()) return fallback;
  const Json& v = j.at(key);
  if (!v.is_boolean()) throw InputError(file, Field(key) + " must be true or false, not " + TypeName(v));
  return v.get<bool>();
}

std::string JsonStringOr(const Json& j, const std::string& key, const std::string& fallback, const std::string& file) {
  if (!j.is_object() || !j.contains(key) || j.at(key).is_null()) return fallback;
  const Json& v = j.at(key);
  if (!v.is_string()) throw InputError(file, Field(key) + " must be a string, not " + TypeName(v));
  return v.get<std::string>();
}

std::vector<double> JsonNumbers(const Json& j, const std::string& key, int n, const std::string& file) {
  if (!j.is_object() || !j.contains(key)) throw InputError(file, "missing " + Field(key));
  const Json& a = j.at(key);
  const std::string want = n >= 0 ? std::to_string(n) + " finite numbers" : "finite numbers";
  if (!a.is_array() || (n >= 0 && a.size() != static_cast<size_t>(n))) {
    throw InputError(file, Field(key) + " must be an array of " + want);
  }
  std::vector<double> v;
  for (const auto& x : a) {
    if (!x.is_number() || !std::isfinite(x.get<double>())) throw InputError(file, Field(key) + " must hold " + want);
    v.push_back(x.get<double>());
  }
  return v;
}

}  // namespace ssiu
