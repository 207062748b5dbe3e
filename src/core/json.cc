#include "core/json.h"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>

#include "core/error.h"

namespace ssiu {

Json ReadJsonFile(const std::string& path) {
  // A directory opens as a stream on Linux and then fails inside the parser with an I/O exception.
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) throw InputError(path, "is a directory, not a JSON file");
  std::ifstream in(path);
  if (!in) throw InputError(path, "cannot open file");
  try {
    return Json::parse(in, nullptr, true, /*ignore_comments=*/true);
  } catch (const Json::exception& e) {  // parse_error, and out_of_range for a number overflow (1e999)
    throw InputError(path, std::string("not valid JSON (") + e.what() + ")");
  } catch (const std::ios_base::failure&) {
    throw InputError(path, "read error");
  }
}

void WriteJsonFile(const std::string& path, const Json& j) {
  if (path == "-") {
    std::cout << j.dump(2) << "\n";
    return;
  }
  std::ofstream out(path);
  if (!out) throw InputError(path, "cannot write file");
  out << j.dump(2) << "\n";
  if (!out) throw InputError(path, "write failed");
}

double JsonNumber(const Json& j, const std::string& key, const std::string& file) {
  if (!j.is_object() || !j.contains(key)) throw InputError(file, "missing field '" + key + "'");
  const Json& v = j.at(key);
  if (!v.is_number()) throw InputError(file, "field '" + key + "' is not a number");
  const double d = v.get<double>();
  if (!std::isfinite(d)) throw InputError(file, "field '" + key + "' is not finite");
  return d;
}

double JsonNumberOr(const Json& j, const std::string& key, double fallback, const std::string& file) {
  if (!j.is_object() || !j.contains(key) || j.at(key).is_null()) return fallback;
  return JsonNumber(j, key, file);
}

}  // namespace ssiu
