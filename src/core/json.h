// JSON I/O at the edges (nlohmann-json), with errors that name the file.
//
// Every JSON input is read strictly (docs/conventions.md: unknown keys are an error, never ignored):
// ReadJsonFile refuses duplicate keys at any depth, each reader calls CheckKeys on every object it
// reads (an unknown or misspelt key is refused, naming the nearest allowed key), and the typed reads
// below refuse a wrong type or an out-of-range integer naming the key.
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace ssiu {

using Json = nlohmann::json;

// Reads and parses a JSON file; InputError naming the file on a missing file, a parse error or a
// duplicate key (nlohmann keeps the last of two silently).
Json ReadJsonFile(const std::string& path);
// Parses JSON text as ReadJsonFile does; `file` names it in errors.
Json ParseJsonStrict(const std::string& text, const std::string& file);
// Writes pretty JSON to a file atomically (core/output.h), or to stdout when path is "-".
// InputError naming the file when it cannot be written.
void WriteJsonFile(const std::string& path, const Json& j);

// Refuses (InputError naming `file` and the key) an object `j` with a key not in `allowed`,
// suggesting the nearest allowed key when one is close ("did you mean 'principal_point'?").
// InputError when `j` is not an object.
void CheckKeys(const Json& j, const std::vector<std::string>& allowed, const std::string& file);
// The allowed key nearest to `key` by edit distance (transposition counts 1), or "" when none is
// within a third of the key's length.
std::string NearestKey(const std::string& key, const std::vector<std::string>& allowed);

// Typed field access that names the file and field in its error. The "Or" forms return `fallback`
// when the key is absent or null, and refuse a present value of the wrong type.
double JsonNumber(const Json& j, const std::string& key, const std::string& file);
double JsonNumberOr(const Json& j, const std::string& key, double fallback, const std::string& file);
// A whole number in [lo, hi]: range checked before any conversion (an out-of-range double-to-int
// cast is undefined behaviour, and 4294967299 must not become 3 or INT_MIN).
int64_t JsonInt(const Json& j, const std::string& key, int64_t lo, int64_t hi, const std::string& file);
int64_t JsonIntOr(const Json& j, const std::string& key, int64_t fallback, int64_t lo, int64_t hi,
                  const std::string& file);
bool JsonBoolOr(const Json& j, const std::string& key, bool fallback, const std::string& file);
std::string JsonStringOr(const Json& j, const std::string& key, const std::string& fallback, const std::string& file);
// An array of exactly `n` finite numbers (n < 0: any length).
std::vector<double> JsonNumbers(const Json& j, const std::string& key, int n, const std::string& file);

}  // namespace ssiu
