#include "cli/batch.h"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <map>
#include <mutex>
#include <stdexcept>
#include <thread>

#include "core/error.h"
#include "core/output.h"

namespace ssiu::cli {
namespace {

using Clock = std::chrono::steady_clock;

double SecondsSince(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// One input's outcome, serialised, waiting for its turn to be written.
struct Slot {
  bool done = false;
  std::string status;  // "error" when the input failed
  bool internal = false;
  std::string error;  // the one-line message of a failed input
  std::string json_line, csv_line;
};

std::string CsvLine(const std::vector<std::string>& cells) { return CsvJoin(cells) + "\n"; }

// JSON Lines: compact, one object per line; a file name that is not UTF-8 is written with U+FFFD
// rather than failing the record.
std::string JsonLine(const Json& j) { return j.dump(-1, ' ', false, Json::error_handler_t::replace) + "\n"; }

Slot Run(const BatchWork& work, const std::string& input, size_t columns) {
  Slot s;
  try {
    BatchRecord r = work(input);
    if (r.csv_row.size() != columns) throw std::logic_error("batch: CSV row does not match its header");
    r.json["file"] = input;
    s.status = r.json.value("status", "");
    s.json_line = JsonLine(r.json);
    s.csv_line = CsvLine(r.csv_row);
    return s;
  } catch (const InputError& e) {
    s.error = e.what();
  } catch (const std::exception& e) {
    s.error = std::string("internal error: ") + e.what();
    s.internal = true;
  } catch (...) {
    s.error = "internal error";
    s.internal = true;
  }
  s.status = "error";
  s.json_line = JsonLine({{"file", input}, {"status", "error"}, {"error", s.error}, {"message", s.error}});
  std::vector<std::string> row(columns);
  row[0] = CsvText(input);
  row[1] = "error";
  row[columns - 1] = CsvText(s.error);
  s.csv_line = CsvLine(row);
  return s;
}

// Worker threads: each takes the next input, runs it and leaves the result in the input's slot; the
// caller takes the slots in input order (results that finish early wait there).
class Pool {
 public:
  Pool(const std::vector<std::string>& inputs, const BatchWork& work, size_t columns, int threads)
      : inputs_(inputs), work_(work), columns_(columns), slots_(inputs.size()) {
    for (int t = 0; t < threads; ++t) threads_.emplace_back([this] { Work(); });
  }
  ~Pool() {
    stop_ = true;  // a write failed: finish the inputs being run, start no more
    for (auto& t : threads_) t.join();
  }
  Slot Take(size_t i) {
    std::unique_lock<std::mutex> lock(mutex_);
    ready_.wait(lock, [&] { return slots_[i].done; });
    return std::move(slots_[i]);
  }

 private:
  void Work() {
    for (size_t i = next_++; i < inputs_.size() && !stop_; i = next_++) {
      Slot s = Run(work_, inputs_[i], columns_);
      s.done = true;
      {
        std::lock_guard<std::mutex> lock(mutex_);
        slots_[i] = std::move(s);
      }
      ready_.notify_all();
    }
  }

  const std::vector<std::string>& inputs_;
  const BatchWork& work_;
  const size_t columns_;
  std::vector<Slot> slots_;
  std::atomic<size_t> next_{0};
  std::atomic<bool> stop_{false};
  std::mutex mutex_;
  std::condition_variable ready_;
  std::vector<std::thread> threads_;
};

std::string Duration(double s) {
  s = std::min(s, 3.6e8);  // 100000 h: keeps the int casts below in range
  char buf[32];
  if (s < 60) {
    std::snprintf(buf, sizeof buf, "%.0f s", s);
  } else if (s < 3600) {
    std::snprintf(buf, sizeof buf, "%dm%02ds", static_cast<int>(s / 60), static_cast<int>(s) % 60);
  } else {
    std::snprintf(buf, sizeof buf, "%dh%02dm", static_cast<int>(s / 3600), static_cast<int>(s / 60) % 60);
  }
  return buf;
}

// "\r123/5000 inputs, 45.6/s, 1m47s left" on a terminal; the line is overwritten in place.
void Progress(const std::string& command, size_t done, size_t total, size_t failed, double elapsed_s) {
  const double rate = done / std::max(elapsed_s, 1e-9);
  std::string line = "\r\033[K" + command + ": " + std::to_string(done) + "/" + std::to_string(total) + " inputs";
  char buf[96];
  std::snprintf(buf, sizeof buf, ", %.1f/s", rate);
  line += buf;
  if (done < total && rate > 0) line += ", " + Duration((total - done) / rate) + " left";
  if (failed) line += ", " + std::to_string(failed) + " failed";
  std::cerr << line << std::flush;
}

}  // namespace

bool BatchFlags::given() const {
  for (const CLI::Option* o : {list_opt, jsonl_opt, csv_opt}) {
    if (o && o->count() > 0) return true;
  }
  return false;
}

void AddBatchFlags(CLI::App* cmd, BatchFlags* f, const std::string& record) {
  f->list_opt =
      cmd->add_option("--list", f->list, "Batch: a file with one input path per line (after the positional ones)");
  f->jsonl_opt = cmd->add_option(
      "--jsonl", f->jsonl,
      "Batch: JSON Lines, one object per input in input order: " + record +
          " plus \"file\"; a failed input is {\"file\", \"status\": \"error\", \"error\", \"message\"} (default "
          "for a batch: stdout)");
  f->csv_opt = cmd->add_option("--csv", f->csv, "Batch: a CSV table, one row per input in input order (- for stdout)");
  cmd->add_option("--threads", f->threads, "Batch: worker threads (0 = all cores)")->capture_default_str();
}

std::vector<std::string> BatchInputs(const std::vector<std::string>& positional, const BatchFlags& f) {
  if (f.threads < 0) throw InputError("--threads", "must be >= 0 (0: all cores)");
  if (!f.jsonl.empty() && f.jsonl == f.csv) throw InputError("--csv", "is the --jsonl file too");
  std::vector<std::string> inputs = positional;
  if (f.list.empty()) return inputs;
  std::ifstream in(f.list);
  if (!in) throw InputError(f.list, "cannot read the input list");
  std::string line;
  while (std::getline(in, line)) {
    const size_t a = line.find_first_not_of(" \t\r");
    if (a == std::string::npos || line[a] == '#') continue;
    const size_t b = line.find_last_not_of(" \t\r");
    inputs.push_back(line.substr(a, b - a + 1));
  }
  if (in.bad()) throw InputError(f.list, "read failed");
  return inputs;
}

bool IsCentroidCsv(const std::string& path) {
  if (path.size() < 4) return false;
  std::string ext = path.substr(path.size() - 4);
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  return ext == ".csv";
}

std::string CsvNumber(const Json& v) {
  if (!v.is_number()) return "";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.12g", v.get<double>());
  return buf;
}

std::string CsvJoin(const std::vector<std::string>& cells) {
  std::string line;
  for (size_t i = 0; i < cells.size(); ++i) line += (i ? "," : "") + cells[i];
  return line;
}

std::string CsvText(const std::string& s) {
  if (s.find_first_of(",\"\r\n") == std::string::npos) return s;
  std::string q = "\"";
  for (char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c);
  return q + "\"";
}

void RunBatch(const std::string& command, const std::vector<std::string>& inputs, const BatchFlags& f,
              const std::vector<std::string>& csv_header, const BatchWork& work) {
  if (inputs.empty()) throw InputError(command, "no inputs (give paths or --list FILE)");
  if (csv_header.size() < 3 || csv_header[0] != "file" || csv_header[1] != "status" || csv_header.back() != "message") {
    throw std::logic_error("batch: the CSV header must start with file,status and end with message");
  }
  const int cores = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  const int threads = static_cast<int>(std::min<size_t>(f.threads > 0 ? f.threads : cores, inputs.size()));
  const bool tty = ::isatty(STDERR_FILENO) == 1;
  const auto t0 = Clock::now();
  size_t failed = 0, internal = 0;
  std::map<std::string, size_t> by_status;

  // Both outputs are streamed in input order while the pool runs; each goes to its temporary and is
  // renamed when complete (an interrupted run leaves no partial file, nor a changed old one).
  auto stream = [&](std::ostream* jsonl, std::ostream* csv) {
    if (csv) *csv << CsvLine(csv_header);
    Pool pool(inputs, work, csv_header.size(), threads);
    auto last = Clock::now();
    for (size_t i = 0; i < inputs.size(); ++i) {
      const Slot s = pool.Take(i);
      if (jsonl) *jsonl << s.json_line;
      if (csv) *csv << s.csv_line;
      ++by_status[s.status];
      if (!s.error.empty()) {
        ++failed;
        internal += s.internal;
        std::cerr << (tty ? "\r\033[K" : "") << "ssiu: error: " << s.error << "\n";
      }
      if (tty && (SecondsSince(last) > 0.2 || i + 1 == inputs.size())) {
        Progress(command, i + 1, inputs.size(), failed, SecondsSince(t0));
        last = Clock::now();
      }
    }
    if (tty) std::cerr << "\n";
  };
  const std::string jsonl = f.jsonl.empty() && f.csv.empty() ? "-" : f.jsonl;
  if (!jsonl.empty() && !f.csv.empty()) {
    WriteFileAtomic(jsonl, [&](std::ostream& j) { WriteFileAtomic(f.csv, [&](std::ostream& c) { stream(&j, &c); }); });
  } else if (!jsonl.empty()) {
    WriteFileAtomic(jsonl, [&](std::ostream& j) { stream(&j, nullptr); });
  } else {
    WriteFileAtomic(f.csv, [&](std::ostream& c) { stream(nullptr, &c); });
  }

  const double dt = SecondsSince(t0);
  char rate[96];
  std::snprintf(rate, sizeof rate, " inputs in %.3f s (%.1f/s, %d threads):", dt, inputs.size() / std::max(dt, 1e-9),
                threads);
  std::cerr << command << ": " << inputs.size() << rate;
  for (const auto& [status, n] : by_status) std::cerr << " " << n << " " << status;
  std::cerr << "\n";
  const std::string what = std::to_string(failed) + " of " + std::to_string(inputs.size()) + " inputs failed";
  if (internal) throw std::runtime_error(what + " (" + std::to_string(internal) + " with an internal error)");
  if (failed) throw InputError(command, what + " (status \"error\" in their records)");
}

}  // namespace ssiu::cli
