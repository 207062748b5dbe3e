// JSON I/O at the edges (nlohmann-json), with errors that name the file.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

namespace ssiu {

using Json = nlohmann::json;

// Reads and parses a JSON file; InputError naming the file on a missing file or a parse error.
Json ReadJsonFile(const std::string& path);
// Writes pretty JSON to a file, or to stdout when path is "-". InputError when it cannot be written.
void WriteJsonFile(const std::string& path, const Json& j);

// Typed field access that names the file and field in its error.
double JsonNumber(const Json& j, const std::string& key, const std::string& file);
double JsonNumberOr(const Json& j, const std::string& key, double fallback, const std::string& file);

}  // namespace ssiu
