// Batch runs of `ssiu solve` and `ssiu detect` (issue 17): every record equals the single-input
// JSON of that input (run one process per input as the independent truth), input order kept on
// several threads, an error record for a bad input in the middle (exit 1, the rest still done),
// --list, the --csv columns, and a progress line when, and only when, stderr is a terminal.
#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/json.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

using Result = testing::SsiuResult;
using ::testing::HasSubstr;
using ::testing::Not;
Result Ssiu(const std::string& args) { return testing::RunSsiu(args); }

std::vector<std::string> Lines(const std::string& path) {
  std::ifstream in(path);
  std::vector<std::string> lines;
  for (std::string l; std::getline(in, l);) lines.push_back(l);
  return lines;
}

// Runs `ssiu args` with stdout and stderr on a fresh pseudo-terminal (as in an interactive shell);
// returns what the terminal received and sets *status to the exit status.
std::string RunOnTerminal(const std::string& args, int* status) {
  const int master = ::posix_openpt(O_RDWR | O_NOCTTY);
  if (master < 0 || ::grantpt(master) != 0 || ::unlockpt(master) != 0) return "no pseudo-terminal";
  const std::string slave = ::ptsname(master);
  const std::string command = testing::SsiuProgram() + " " + args;
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::setsid();
    const int fd = ::open(slave.c_str(), O_RDWR);
    if (fd < 0) ::_exit(126);
    ::dup2(fd, STDOUT_FILENO);
    ::dup2(fd, STDERR_FILENO);
    ::close(master);
    ::execl("/bin/sh", "sh", "-c", command.c_str(), static_cast<char*>(nullptr));
    ::_exit(127);
  }
  std::string shown;
  char buf[4096];
  for (;;) {  // read until the child's side closes (EIO on Linux)
    const ssize_t n = ::read(master, buf, sizeof buf);
    if (n > 0) {
      shown.append(buf, static_cast<size_t>(n));
    } else if (n < 0 && errno == EINTR) {
      continue;
    } else {
      break;
    }
  }
  ::close(master);
  int w = 0;
  ::waitpid(pid, &w, 0);
  *status = WIFEXITED(w) ? WEXITSTATUS(w) : -1;
  return shown;
}

// The record without its run times (and "file", which the single-input JSON does not have).
Json WithoutTiming(Json j) {
  j.erase("timing_ms");
  j.erase("file");
  return j;
}

class BatchCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new std::string(testing::TempDir("batch_cli"));
    ASSERT_EQ(Ssiu("catalog build --fov-deg 16.6 --out " + P("cat")).status, 0);
    // Three frames and the centroid list of a fourth attitude; a corrupt "frame".
    ASSERT_EQ(Ssiu("simulate frame --random --seed 300 --count 4 --scene-csv --out " + P("f")).status, 0);
    std::ofstream(P("bad.png")) << "not an image";
    inputs_ = new std::vector<std::string>{P("f/frame_0000.png"), P("f/frame_0001.png"), P("bad.png"),
                                           P("f/frame_0002.png"), P("f/frame_0003_centroids.csv")};
  }
  static void TearDownTestSuite() {
    delete dir_;
    delete inputs_;
  }
  static std::string P(const std::string& n) { return *dir_ + "/" + n; }
  static std::string Cam() { return " --camera " + P("f/camera.json") + " --catalog " + P("cat"); }
  static std::string* dir_;
  static std::vector<std::string>* inputs_;
};
std::string* BatchCli::dir_ = nullptr;
std::vector<std::string>* BatchCli::inputs_ = nullptr;

TEST_F(BatchCli, SolveBatchEqualsSingleSolvesInOrderWithAnErrorRecord) {
  std::string all;
  for (const auto& in : *inputs_) all += " " + in;
  const Result b = Ssiu("solve" + all + Cam() + " --threads 2 --jsonl " + P("s.jsonl") + " --csv " + P("s.csv"));
  EXPECT_EQ(b.status, 1) << b.output;  // one input failed, the others were solved
  EXPECT_THAT(b.output, HasSubstr("bad.png: cannot decode image"));
  EXPECT_THAT(b.output, HasSubstr("1 of 5 inputs failed"));
  EXPECT_THAT(b.output, Not(HasSubstr("\r")));  // stderr is a pipe here: no progress line
  EXPECT_THAT(b.output, Not(HasSubstr(" left")));

  const std::vector<std::string> lines = Lines(P("s.jsonl"));
  ASSERT_EQ(lines.size(), inputs_->size());
  const std::vector<std::string> csv = Lines(P("s.csv"));
  ASSERT_EQ(csv.size(), inputs_->size() + 1);
  EXPECT_EQ(csv[0],
            "file,status,mode,ra_deg,dec_deg,roll_deg,q_w,q_x,q_y,q_z,sigma_cross_arcsec,sigma_roll_arcsec,"
            "focal_length_px,num_centroids,num_matches,false_match_probability,time_ms,message");
  for (size_t i = 0; i < inputs_->size(); ++i) {
    const std::string& in = (*inputs_)[i];
    const Json rec = Json::parse(lines[i]);
    EXPECT_EQ(rec["file"], in);  // input order, although two threads finished in any order
    EXPECT_EQ(csv[i + 1].substr(0, in.size() + 1), in + ",");
    if (in == P("bad.png")) {
      EXPECT_EQ(rec["status"], "error");
      EXPECT_THAT(rec["error"].get<std::string>(), HasSubstr("cannot decode image"));
      EXPECT_THAT(csv[i + 1], HasSubstr(",error,"));
      continue;
    }
    // The independent truth: one `ssiu solve` process per input, its --json.
    const bool centroids = in.size() > 4 && in.substr(in.size() - 4) == ".csv";
    const Result s =
        Ssiu("solve " + std::string(centroids ? "--centroids " : "") + in + Cam() + " --json " + P("one.json"));
    ASSERT_EQ(s.status, 0) << s.output;
    const Json one = ReadJsonFile(P("one.json"));
    EXPECT_EQ(one["status"], "solved") << in;
    EXPECT_EQ(WithoutTiming(rec), WithoutTiming(one)) << in;
    EXPECT_TRUE(rec.contains("timing_ms"));
    // The CSV row carries the same attitude (12 significant digits).
    std::vector<std::string> cells;
    std::stringstream row(csv[i + 1]);
    for (std::string c; std::getline(row, c, ',');) cells.push_back(c);
    ASSERT_GE(cells.size(), 16u) << csv[i + 1];
    EXPECT_EQ(cells[1], "solved");
    EXPECT_NEAR(std::stod(cells[3]), one["ra_deg"].get<double>(), 1e-9);
    EXPECT_NEAR(std::stod(cells[6]), one["q"][0].get<double>(), 1e-11);
    EXPECT_EQ(std::stoul(cells[14]), one["matches"].size());
  }
}

TEST_F(BatchCli, SolveListAndCentroidsFlagsAreOneBatch) {
  // --list: one path per line, blanks and '#' comments skipped; after the positional inputs.
  std::ofstream(P("list.txt")) << "# frames\n" << (*inputs_)[1] << "\n\n  " << (*inputs_)[3] << "  \n";
  const Result r = Ssiu("solve " + (*inputs_)[0] + " --list " + P("list.txt") + " --centroids " + (*inputs_)[4] +
                        Cam() + " --jsonl " + P("l.jsonl"));
  ASSERT_EQ(r.status, 0) << r.output;
  const std::vector<std::string> lines = Lines(P("l.jsonl"));
  ASSERT_EQ(lines.size(), 4u);
  // Order: positional, then --centroids, then the list.
  const std::vector<std::string> want = {(*inputs_)[0], (*inputs_)[4], (*inputs_)[1], (*inputs_)[3]};
  for (size_t i = 0; i < want.size(); ++i) {
    const Json rec = Json::parse(lines[i]);
    EXPECT_EQ(rec["file"], want[i]);
    EXPECT_EQ(rec["status"], "solved") << want[i];
  }
  // A list that cannot be read, and single-input outputs in a batch, are usage errors (exit 1).
  EXPECT_EQ(Ssiu("solve --list " + P("nolist.txt") + Cam()).status, 1);
  const Result o = Ssiu("solve " + (*inputs_)[0] + " " + (*inputs_)[1] + Cam() + " --overlay " + P("o.png"));
  EXPECT_EQ(o.status, 1);
  EXPECT_THAT(o.output, HasSubstr("--overlay"));
}

TEST_F(BatchCli, ProgressLineOnlyOnATerminal) {
  // 125 inputs (the frames and the list again and again, the bad one among them) on a terminal.
  std::string all;
  for (int k = 0; k < 25; ++k) {
    for (const auto& in : *inputs_) all += " " + in;
  }
  int status = -1;
  const std::string shown = RunOnTerminal("solve" + all + Cam() + " --threads 2 --jsonl " + P("t.jsonl"), &status);
  EXPECT_EQ(status, 1) << shown;  // the bad input, 25 times
  EXPECT_EQ(Lines(P("t.jsonl")).size(), 125u);
  // Each progress line is redrawn in place ("\r" + erase to the end of line): done/total, the rate, the
  // failures so far, and the time left while inputs remain (a redraw every 0.2 s, so how many
  // there are depends on the machine); the last one shows 125/125.
  std::vector<std::string> updates;
  for (size_t p = shown.find("\r\033[Kssiu solve: "); p != std::string::npos;
       p = shown.find("\r\033[Kssiu solve: ", p + 1)) {
    const size_t end = shown.find_first_of("\r\n", p + 1);
    updates.push_back(shown.substr(p + 4, end == std::string::npos ? std::string::npos : end - p - 4));
  }
  ASSERT_FALSE(updates.empty()) << shown;
  EXPECT_THAT(updates.back(), ::testing::MatchesRegex("ssiu solve: 125/125 inputs, [0-9.]+/s, 25 failed")) << shown;
  for (size_t i = 0; i + 1 < updates.size(); ++i) {
    // The time left reads "42 s", "1m01s" or "2h05m" (a slow machine's first estimate can pass a minute).
    EXPECT_THAT(updates[i], ::testing::MatchesRegex("ssiu solve: [0-9]+/125 inputs, [0-9.]+/s, "
                                                    "([0-9]+ s|[0-9]+m[0-9][0-9]s|[0-9]+h[0-9][0-9]m) left.*"))
        << shown;
  }
  EXPECT_THAT(shown, HasSubstr("bad.png: cannot decode image"));  // errors still shown, on their own line
}

TEST_F(BatchCli, DetectBatchEqualsSingleDetects) {
  const std::vector<std::string> in = {(*inputs_)[0], (*inputs_)[2], (*inputs_)[1]};
  const Result b = Ssiu("detect " + in[0] + " " + in[1] + " " + in[2] + " --camera " + P("f/camera.json") +
                        " --threads 2 --jsonl " + P("d.jsonl") + " --csv " + P("d.csv"));
  EXPECT_EQ(b.status, 1) << b.output;
  EXPECT_THAT(b.output, Not(HasSubstr("\r")));
  const std::vector<std::string> lines = Lines(P("d.jsonl"));
  const std::vector<std::string> csv = Lines(P("d.csv"));
  ASSERT_EQ(lines.size(), 3u);
  ASSERT_EQ(csv.size(), 4u);
  EXPECT_EQ(csv[0],
            "file,status,width,height,num_stars,num_rejected,background_adu,noise_adu,psf_sigma_px,time_ms,message");
  for (size_t i = 0; i < in.size(); ++i) {
    Json rec = Json::parse(lines[i]);
    EXPECT_EQ(rec["file"], in[i]);
    if (i == 1) {
      EXPECT_EQ(rec["status"], "error");
      EXPECT_THAT(csv[i + 1], HasSubstr(",error,"));
      continue;
    }
    ASSERT_EQ(Ssiu("detect " + in[i] + " --camera " + P("f/camera.json") + " --json " + P("one.json")).status, 0);
    Json one = ReadJsonFile(P("one.json"));
    EXPECT_EQ(rec["status"], "ok");
    rec.erase("status");
    EXPECT_EQ(rec["file"], one["file"]);
    EXPECT_EQ(WithoutTiming(rec), WithoutTiming(one)) << in[i];
    EXPECT_EQ(csv[i + 1].substr(0, in[i].size() + 1 + 3 + 10), in[i] + ",ok,1024,1024,") << csv[i + 1];
  }
}

}  // namespace
}  // namespace ssiu
