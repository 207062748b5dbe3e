// Batch runs of `ssiu solve` and `ssiu detect`: many inputs in one process, each independent, on a
// pool of threads, written in input order as JSON Lines and/or a CSV table (docs/identify.md "Batch").
// A subcommand supplies the work of one input; this file owns the flags, the threads, the ordering,
// the error records, the progress bar and the outputs.
#pragma once

#include <CLI/CLI.hpp>
#include <functional>
#include <string>
#include <vector>

#include "core/json.h"

namespace ssiu::cli {

struct BatchFlags {
  std::string list;   // --list FILE: one input per line
  std::string jsonl;  // --jsonl FILE (- for stdout)
  std::string csv;    // --csv FILE (- for stdout)
  int threads = 0;    // --threads N, 0 = all cores
  CLI::Option* list_opt = nullptr;
  CLI::Option* jsonl_opt = nullptr;
  CLI::Option* csv_opt = nullptr;
  // A batch flag was given (the run is a batch even with one input).
  bool given() const;
};

// Adds --list, --jsonl, --csv and --threads to `cmd`; `record` names what one JSON line holds.
void AddBatchFlags(CLI::App* cmd, BatchFlags* f, const std::string& record);

// The inputs in order: `positional`, then the lines of --list (surrounding blanks trimmed; empty lines
// and lines starting with '#' skipped). InputError naming the list file when it cannot be read.
std::vector<std::string> BatchInputs(const std::vector<std::string>& positional, const BatchFlags& f);

// True for a centroid list (the name ends in .csv, any case) rather than a frame.
bool IsCentroidCsv(const std::string& path);

// One input's outcome: its JSON object ("file" is added) and its CSV row, one cell per column.
struct BatchRecord {
  Json json;
  std::vector<std::string> csv_row;
};
// The work of one input; runs on several threads at once (must only share const state). An
// InputError (or any exception) makes that input an error record; the run goes on.
using BatchWork = std::function<BatchRecord(const std::string& input)>;

// Runs `work` on every input on f.threads threads and writes the records in input order: --jsonl one
// JSON object per line, --csv a header line `csv_header` then one row per input (neither given: JSON
// Lines on stdout). csv_header starts with file,status and ends with message: a failed input's row
// has those three cells and the others empty; its JSON is {"file", "status": "error", "error",
// "message"}. Outputs are streamed to a hidden temporary and renamed at the end (core/output.h), so an
// interrupted run leaves no partial file. A progress line (done/total, rate, time left) goes to
// stderr only when stderr is a terminal; every failed input is reported there as one line, and a
// summary line (counts by status, rate) at the end. Then InputError (exit 1) when any input failed;
// std::runtime_error (exit 2) when any failed with an internal error.
void RunBatch(const std::string& command, const std::vector<std::string>& inputs, const BatchFlags& f,
              const std::vector<std::string>& csv_header, const BatchWork& work);

// CSV cells: a number (12 significant digits; empty for null or a non-number), text (quoted per
// RFC 4180 when it holds a comma, quote or line break).
std::string CsvNumber(const Json& v);
std::string CsvText(const std::string& s);
// Cells joined by commas (a header line without its newline).
std::string CsvJoin(const std::vector<std::string>& cells);

}  // namespace ssiu::cli
