// Reading AEM and ACM messages. Both encodings become one stream of items (a keyword and its value,
// a block start/stop, a data line, each with its line number): KVN line by line (504.0-B-2 sec. 6),
// XML through a small reader of the NDM/XML subset (elements, attributes, text, comments; no DTD), its
// elements mapped to the KVN keywords they stand for. One parser then checks and reads the items.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <fstream>
#include <map>
#include <memory>
#include <set>
#include <sstream>

#include "ccsds/adm.h"
#include "core/error.h"

namespace ssiu {
namespace {

enum class Kind { kKey, kStart, kStop, kData };
struct Item {
  Kind kind;
  std::string key, value;  // kStart/kStop: the block name (META, DATA, ATT, ...); kData: value
  int line;
};

std::string Trim(const std::string& s) {
  size_t a = 0, b = s.size();
  while (a < b && std::isspace(static_cast<unsigned char>(s[a]))) ++a;
  while (b > a && std::isspace(static_cast<unsigned char>(s[b - 1]))) --b;
  return s.substr(a, b - a);
}
std::string Upper(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::toupper(c); });
  return s;
}
bool IsKeyword(const std::string& s) {
  return !s.empty() && std::all_of(s.begin(), s.end(),
                                   [](unsigned char c) { return std::isupper(c) || std::isdigit(c) || c == '_'; });
}

// KVN (sec. 6.4): `KEY = value [units]`, `COMMENT text`, `BLOCK_START`/`BLOCK_STOP`, data lines.
std::vector<Item> LexKvn(const std::string& text) {
  std::vector<Item> items;
  std::istringstream is(text);
  std::string raw;
  int line = 0;
  while (std::getline(is, raw)) {
    ++line;
    const std::string s = Trim(raw);
    if (s.empty()) continue;
    if (s.rfind("COMMENT", 0) == 0 && (s.size() == 7 || std::isspace(static_cast<unsigned char>(s[7])))) {
      items.push_back({Kind::kKey, "COMMENT", Trim(s.substr(7)), line});
      continue;
    }
    const size_t eq = s.find('=');
    if (eq != std::string::npos && IsKeyword(Trim(s.substr(0, eq)))) {
      std::string v = Trim(s.substr(eq + 1));
      if (!v.empty() && v.back() == ']') {  // units in brackets are informative (sec. 6.4.6)
        const size_t lb = v.rfind('[');
        if (lb != std::string::npos) v = Trim(v.substr(0, lb));
      }
      items.push_back({Kind::kKey, Trim(s.substr(0, eq)), v, line});
      continue;
    }
    if (IsKeyword(s) && s.size() > 6 && s.compare(s.size() - 6, 6, "_START") == 0) {
      items.push_back({Kind::kStart, s.substr(0, s.size() - 6), "", line});
    } else if (IsKeyword(s) && s.size() > 5 && s.compare(s.size() - 5, 5, "_STOP") == 0) {
      items.push_back({Kind::kStop, s.substr(0, s.size() - 5), "", line});
    } else {
      items.push_back({Kind::kData, "", s, line});
    }
  }
  return items;
}

// ---- A small XML reader: enough for NDM/XML (no DTD, no entities beyond the five predefined). ----
struct Element {
  std::string name, text;
  std::map<std::string, std::string> attrs;
  int line = 0;
  std::vector<std::unique_ptr<Element>> children;
};

class XmlReader {
 public:
  XmlReader(const std::string& text, const std::string& file) : s_(text), file_(file) {}
  std::unique_ptr<Element> Parse() {
    SkipMisc();
    if (pos_ >= s_.size() || s_[pos_] != '<') Fail("no root element");
    auto root = ParseElement();
    SkipMisc();
    if (pos_ < s_.size()) Fail("text after the root element");
    return root;
  }

 private:
  [[noreturn]] void Fail(const std::string& what) const {
    throw InputError(file_ + ":" + std::to_string(line_), "XML: " + what);
  }
  void Advance(size_t n) {
    for (size_t i = 0; i < n && pos_ < s_.size(); ++i, ++pos_)
      if (s_[pos_] == '\n') ++line_;
  }
  bool At(const char* p) const { return s_.compare(pos_, std::char_traits<char>::length(p), p) == 0; }
  void SkipTo(const char* end) {
    const size_t e = s_.find(end, pos_);
    if (e == std::string::npos) Fail(std::string("unterminated construct (no ") + end + ")");
    Advance(e + std::char_traits<char>::length(end) - pos_);
  }
  void SkipSpace() {
    while (pos_ < s_.size() && std::isspace(static_cast<unsigned char>(s_[pos_]))) Advance(1);
  }
  void SkipMisc() {  // declarations, comments, processing instructions, DOCTYPE, blanks
    for (;;) {
      SkipSpace();
      if (At("<?"))
        SkipTo("?>");
      else if (At("<!--"))
        SkipTo("-->");
      else if (At("<!"))
        SkipTo(">");
      else
        return;
    }
  }
  std::string Name() {
    const size_t b = pos_;
    while (pos_ < s_.size() && (std::isalnum(static_cast<unsigned char>(s_[pos_])) || s_[pos_] == '_' ||
                                s_[pos_] == ':' || s_[pos_] == '-' || s_[pos_] == '.'))
      Advance(1);
    if (pos_ == b) Fail("expected a name");
    std::string n = s_.substr(b, pos_ - b);
    const size_t colon = n.find(':');
    return colon == std::string::npos ? n : n.substr(colon + 1);  // a namespace prefix is dropped
  }
  std::string Unescape(const std::string& t) {
    std::string r;
    for (size_t i = 0; i < t.size(); ++i) {
      if (t[i] != '&') {
        r += t[i];
        continue;
      }
      const size_t e = t.find(';', i);
      const std::string ent = e == std::string::npos ? "" : t.substr(i + 1, e - i - 1);
      if (ent == "amp")
        r += '&';
      else if (ent == "lt")
        r += '<';
      else if (ent == "gt")
        r += '>';
      else if (ent == "quot")
        r += '"';
      else if (ent == "apos")
        r += '\'';
      else
        Fail("unknown entity &" + ent + ";");
      i = e;
    }
    return r;
  }
  std::unique_ptr<Element> ParseElement() {
    auto el = std::make_unique<Element>();
    el->line = line_;
    Advance(1);  // '<'
    el->name = Name();
    for (;;) {
      SkipSpace();
      if (At("/>")) {
        Advance(2);
        return el;
      }
      if (At(">")) {
        Advance(1);
        break;
      }
      const std::string an = Name();
      SkipSpace();
      if (!At("=")) Fail("attribute " + an + " without a value");
      Advance(1);
      SkipSpace();
      if (pos_ >= s_.size() || (s_[pos_] != '"' && s_[pos_] != '\'')) Fail("attribute " + an + " not quoted");
      const char q = s_[pos_];
      Advance(1);
      const size_t e = s_.find(q, pos_);
      if (e == std::string::npos) Fail("unterminated attribute " + an);
      el->attrs[an] = Unescape(s_.substr(pos_, e - pos_));
      Advance(e + 1 - pos_);
    }
    for (;;) {
      if (pos_ >= s_.size()) Fail("element <" + el->name + "> not closed");
      if (At("<!--")) {
        SkipTo("-->");
      } else if (At("<![CDATA[")) {
        const size_t e = s_.find("]]>", pos_);
        if (e == std::string::npos) Fail("unterminated CDATA");
        el->text += s_.substr(pos_ + 9, e - pos_ - 9);
        Advance(e + 3 - pos_);
      } else if (At("</")) {
        Advance(2);
        const std::string n = Name();
        if (n != el->name) Fail("</" + n + "> closes <" + el->name + ">");
        SkipSpace();
        if (!At(">")) Fail("bad closing tag </" + n);
        Advance(1);
        return el;
      } else if (At("<?")) {
        SkipTo("?>");
      } else if (At("<")) {
        el->children.push_back(ParseElement());
      } else {
        const size_t e = s_.find('<', pos_);
        const size_t end = e == std::string::npos ? s_.size() : e;
        el->text += Unescape(s_.substr(pos_, end - pos_));
        Advance(end - pos_);
      }
    }
  }

  const std::string& s_;
  std::string file_;
  size_t pos_ = 0;
  int line_ = 1;
};

// Leaf texts of an element in document order (an AEM attitudeState's EPOCH, Q1..QC, rates).
void Leaves(const Element& e, std::vector<std::string>* out) {
  if (e.children.empty()) {
    out->push_back(Trim(e.text));
    return;
  }
  for (const auto& c : e.children) Leaves(*c, out);
}

void EmitKeys(const Element& e, std::vector<Item>* items);

// The KVN items an XML message element stands for. The XML blocks map to KVN blocks: metadata ->
// META, AEM data -> DATA (each attitudeState one data line), ACM att/cov/ad/phys/man/user ->
// ATT/COV/AD/PHYS/MAN/USER, sensorData -> SENSOR; attLine/covLine are data lines.
void EmitMessage(const Element& root, const std::string& file, std::vector<Item>* items) {
  const std::string kind = Upper(root.name);
  const auto v = root.attrs.find("version");
  items->push_back({Kind::kKey, "CCSDS_" + kind + "_VERS", v == root.attrs.end() ? "" : v->second, root.line});
  if (v != root.attrs.end() && v->second != "2.0")
    throw InputError(file + ":" + std::to_string(root.line),
                     "CCSDS_" + kind + "_VERS: XML version " + v->second +
                         " is not read (ADM 2.0 XML is; an ADM 1.0 message is read in KVN)");
  static const std::map<std::string, std::string> blocks = {
      {"metadata", "META"}, {"att", "ATT"},   {"cov", "COV"},           {"ad", "AD"},    {"phys", "PHYS"},
      {"man", "MAN"},       {"user", "USER"}, {"sensorData", "SENSOR"}, {"data", "DATA"}};
  for (const auto& part : root.children) {
    if (part->name == "header") {
      EmitKeys(*part, items);
      continue;
    }
    if (part->name != "body")
      throw InputError(file + ":" + std::to_string(part->line), "XML: unexpected <" + part->name + ">");
    for (const auto& seg : part->children) {
      if (seg->name != "segment")
        throw InputError(file + ":" + std::to_string(seg->line), "XML: unexpected <" + seg->name + ">");
      for (const auto& sec : seg->children) {
        if (sec->name == "metadata") {
          items->push_back({Kind::kStart, "META", "", sec->line});
          EmitKeys(*sec, items);
          items->push_back({Kind::kStop, "META", "", sec->line});
        } else if (sec->name == "data" && kind == "AEM") {
          items->push_back({Kind::kStart, "DATA", "", sec->line});
          for (const auto& st : sec->children) {
            if (st->name == "COMMENT") {
              items->push_back({Kind::kKey, "COMMENT", Trim(st->text), st->line});
              continue;
            }
            std::vector<std::string> leaves;
            Leaves(*st, &leaves);
            std::string line;
            for (const auto& l : leaves) line += (line.empty() ? "" : " ") + l;
            items->push_back({Kind::kData, "", line, st->line});
          }
          items->push_back({Kind::kStop, "DATA", "", sec->line});
        } else if (sec->name == "data") {  // ACM
          for (const auto& blk : sec->children) {
            const auto b = blocks.find(blk->name);
            if (b == blocks.end())
              throw InputError(file + ":" + std::to_string(blk->line), "XML: unexpected <" + blk->name + ">");
            items->push_back({Kind::kStart, b->second, "", blk->line});
            for (const auto& c : blk->children) {
              if (c->name == "attLine" || c->name == "covLine") {
                items->push_back({Kind::kData, "", Trim(c->text), c->line});
              } else if (c->name == "sensorData") {
                items->push_back({Kind::kStart, "SENSOR", "", c->line});
                EmitKeys(*c, items);
                items->push_back({Kind::kStop, "SENSOR", "", c->line});
              } else {
                items->push_back({Kind::kKey, c->name, Trim(c->text), c->line});
              }
            }
            items->push_back({Kind::kStop, b->second, "", blk->line});
          }
        } else {
          throw InputError(file + ":" + std::to_string(sec->line), "XML: unexpected <" + sec->name + ">");
        }
      }
    }
  }
}

void EmitKeys(const Element& e, std::vector<Item>* items) {
  for (const auto& c : e.children) items->push_back({Kind::kKey, c->name, Trim(c->text), c->line});
}

std::vector<Item> LexXml(const std::string& text, const std::string& file) {
  XmlReader reader(text, file);
  const std::unique_ptr<Element> root = reader.Parse();
  std::vector<Item> items;
  if (root->name == "aem" || root->name == "acm") {
    EmitMessage(*root, file, &items);
    return items;
  }
  if (root->name == "ndm") {  // an NDM container (505.0-B-3): its first attitude history
    for (const auto& c : root->children)
      if (c->name == "aem" || c->name == "acm") {
        EmitMessage(*c, file, &items);
        return items;
      }
    throw InputError(file + ":" + std::to_string(root->line),
                     "ndm: holds no AEM or ACM (ssiu reads attitude histories)");
  }
  throw InputError(file + ":" + std::to_string(root->line),
                   "<" + root->name + ">: not an AEM or ACM (ssiu reads attitude histories)");
}

// ---- The parser over items ----

class Parser {
 public:
  Parser(std::vector<Item> items, const std::string& file, const std::string& epoch_utc)
      : items_(std::move(items)), file_(file), epoch_(epoch_utc) {}

  AttitudeHistory Run() {
    h_.file = file_;
    if (items_.empty()) throw InputError(file_, "empty message");
    const Item& first = items_[0];
    if (first.kind != Kind::kKey || (first.key != "CCSDS_AEM_VERS" && first.key != "CCSDS_ACM_VERS")) {
      if (first.kind == Kind::kKey && first.key.rfind("CCSDS_", 0) == 0)
        Fail(first, first.key, "not an AEM or ACM (ssiu reads attitude histories)");
      Fail(first, first.kind == Kind::kKey ? first.key : "CCSDS_AEM_VERS",
           "the message must start with CCSDS_AEM_VERS or CCSDS_ACM_VERS");
    }
    h_.message = first.key == "CCSDS_AEM_VERS" ? AdmMessage::kAem : AdmMessage::kAcm;
    h_.version = first.value;
    if (h_.version != "1.0" && h_.version != "2.0")
      Fail(first, first.key, "version '" + first.value + "' (1.0 or 2.0 are read)");
    if (h_.message == AdmMessage::kAcm && h_.version != "2.0")
      Fail(first, first.key, "the ACM exists only as version 2.0");
    pos_ = 1;
    Header();
    if (h_.message == AdmMessage::kAem)
      Aem();
    else
      Acm();
    h_.epoch_utc = epoch_;
    return std::move(h_);
  }

 private:
  [[noreturn]] void Fail(const Item& it, const std::string& key, const std::string& what) const {
    throw InputError(file_ + ":" + std::to_string(it.line), key + ": " + what);
  }
  [[noreturn]] void FailEnd(const std::string& key, const std::string& what) const {
    const int line = items_.empty() ? 0 : items_.back().line;
    throw InputError(file_ + ":" + std::to_string(line), key + ": " + what);
  }
  bool Done() const { return pos_ >= items_.size(); }
  const Item& Cur() const { return items_[pos_]; }

  double Number(const Item& it, const std::string& key, const std::string& text) const {
    try {
      size_t used = 0;
      const double v = std::stod(text, &used);
      if (used == text.size() && std::isfinite(v)) return v;
    } catch (const std::exception&) {
    }
    Fail(it, key, "'" + text + "' is not a number");
  }
  std::vector<double> Numbers(const Item& it, const std::string& key, const std::string& text) const {
    std::istringstream is(text);
    std::vector<double> v;
    std::string tok;
    while (is >> tok) v.push_back(Number(it, key, tok));
    return v;
  }

  void Header() {
    std::set<std::string> seen;
    static const std::set<std::string> known = {"COMMENT", "CLASSIFICATION", "CREATION_DATE", "ORIGINATOR",
                                                "MESSAGE_ID"};
    while (!Done() && Cur().kind != Kind::kStart) {
      const Item& it = Cur();
      if (it.kind != Kind::kKey) Fail(it, "header", "unexpected line '" + it.value + "'");
      if (!known.count(it.key)) Fail(it, it.key, "not a header keyword");
      if (it.key == "CREATION_DATE") AdmSecondsSince(it.value, "UTC", "2000-01-01T00:00:00", Where(it, it.key));
      seen.insert(it.key);
      ++pos_;
    }
    for (const char* k : {"CREATION_DATE", "ORIGINATOR"})
      if (!seen.count(k)) Done() ? FailEnd(k, "missing in the header") : Fail(Cur(), k, "missing in the header");
  }
  std::string Where(const Item& it, const std::string& key) const {
    return file_ + ":" + std::to_string(it.line) + ": " + key;
  }

  // Keywords of a block up to its stop; unknown ones are an error unless `known` is empty.
  std::map<std::string, const Item*> Block(const std::string& name, const std::set<std::string>& known,
                                           std::vector<const Item*>* data = nullptr,
                                           std::vector<std::map<std::string, const Item*>>* sensors = nullptr) {
    std::map<std::string, const Item*> kv;
    const Item& start = Cur();
    ++pos_;
    for (;;) {
      if (Done()) Fail(start, name + "_START", "no " + name + "_STOP");
      const Item& it = Cur();
      if (it.kind == Kind::kStop) {
        if (it.key != name) Fail(it, it.key + "_STOP", "inside " + name + "_START");
        ++pos_;
        return kv;
      }
      if (it.kind == Kind::kStart) {
        if (it.key == "SENSOR" && sensors) {
          sensors->push_back(
              Block("SENSOR", {"COMMENT", "SENSOR_NUMBER", "SENSOR_USED", "NUMBER_SENSOR_NOISE_COVARIANCE",
                               "SENSOR_NOISE_STDDEV", "SENSOR_FREQUENCY"}));
          continue;
        }
        if (known.empty()) {  // a section ssiu does not read: nested blocks too
          Block(it.key, {});
          continue;
        }
        Fail(it, it.key + "_START", "inside " + name + "_START");
      }
      if (it.kind == Kind::kData) {
        if (!data) {
          if (!known.empty()) Fail(it, name, "unexpected line '" + it.value + "'");
        } else {
          data->push_back(&it);
        }
        ++pos_;
        continue;
      }
      if (data && !data->empty() && it.key != "COMMENT") Fail(it, it.key, "keyword among the data lines");
      if (!known.empty() && !known.count(it.key))
        Fail(it, it.key, "not " + std::string(name == "ATT" || name == "AD" ? "an " : "a ") + name + " keyword");
      if (it.key != "COMMENT") {
        if (kv.count(it.key)) Fail(it, it.key, "given twice");
        kv[it.key] = &it;
      } else if (name == "META" || name == "ATT") {
        h_.comments.push_back(it.value);
      }
      ++pos_;
    }
  }
  const Item* Need(const std::map<std::string, const Item*>& kv, const std::string& key, const Item& block) const {
    const auto f = kv.find(key);
    if (f == kv.end()) Fail(block, key, "missing");
    return f->second;
  }
  std::string Get(const std::map<std::string, const Item*>& kv, const std::string& key) const {
    const auto f = kv.find(key);
    return f == kv.end() ? "" : f->second->value;
  }

  // Which of REF_FRAME_A/B is inertial: +1 A inertial (the quaternion is inertial -> body as ssiu's),
  // -1 B inertial (the inverse).
  int Direction(const Item& a, const Item& b) {
    static const std::set<std::string> inertial = {"ICRF",  "ICRF1", "ICRF2", "ICRF3", "EME2000",
                                                   "J2000", "GCRF",  "MCI",   "TOD",   "MOD"};
    const bool ia = inertial.count(Upper(a.value)) > 0, ib = inertial.count(Upper(b.value)) > 0;
    if (ia == ib)
      Fail(a, "REF_FRAME_A",
           "'" + a.value + "' to '" + b.value +
               "': ssiu reads attitudes between an inertial frame (ICRF, EME2000, J2000, GCRF) and a body frame");
    if (h_.states.empty() || frames_set_ == false) {
      h_.inertial_frame = ia ? a.value : b.value;
      h_.body_frame = ia ? b.value : a.value;
      frames_set_ = true;
    } else if ((ia ? b.value : a.value) != h_.body_frame) {
      Fail(a, "REF_FRAME_B",
           "a second body frame '" + (ia ? b.value : a.value) + "' (the first was " + h_.body_frame + ")");
    }
    return ia ? 1 : -1;
  }
  void SetTimeSystem(const Item& it) {
    const std::string ts = Upper(it.value);
    static const std::set<std::string> ok = {"UTC", "TAI", "TT", "GPS", "TDB"};
    if (!ok.count(ts)) Fail(it, "TIME_SYSTEM", "'" + it.value + "' is not read (UTC, TAI, TT, TDB, GPS are)");
    h_.time_system = ts == "TDB" ? "TT" : ts;  // TDB - TT < 2 ms (the periodic terms): taken as TT
  }
  double Epoch(const Item& it, const std::string& key, const std::string& text) {
    if (epoch_.empty()) epoch_ = AdmEpoch(AdmFirstUtc(it, key, text), 0.0);
    return AdmSecondsSince(text, h_.time_system, epoch_, Where(it, key));
  }
  // The UTC text of an epoch in the message's time system (the origin when none was given).
  std::string AdmFirstUtc(const Item& it, const std::string& key, const std::string& text) {
    const double dt = AdmSecondsSince(text, h_.time_system, "2000-01-01T00:00:00", Where(it, key));
    return AdmEpoch("2000-01-01T00:00:00", dt);
  }

  Quat ToQuat(const Item& it, const std::string& key, double q1, double q2, double q3, double qc, int dir) const {
    const double n = std::sqrt(q1 * q1 + q2 * q2 + q3 * q3 + qc * qc);
    if (!(n > 0.5 && n < 1.5)) Fail(it, key, "quaternion norm " + std::to_string(n) + " is not 1");
    Quat q(qc / n, q1 / n, q2 / n, q3 / n);
    return dir > 0 ? q : q.conjugate();
  }

  void Aem() {
    static const std::set<std::string> meta_keys = {
        "COMMENT",       "OBJECT_NAME",          "OBJECT_ID",           "CENTER_NAME",
        "REF_FRAME_A",   "REF_FRAME_B",          "ATTITUDE_DIR",        "TIME_SYSTEM",
        "START_TIME",    "USEABLE_START_TIME",   "USEABLE_STOP_TIME",   "STOP_TIME",
        "ATTITUDE_TYPE", "QUATERNION_TYPE",      "EULER_ROT_SEQ",       "RATE_FRAME",
        "ANGVEL_FRAME",  "INTERPOLATION_METHOD", "INTERPOLATION_DEGREE"};
    int segments = 0;
    while (!Done()) {
      const Item& start = Cur();
      if (start.kind != Kind::kStart || start.key != "META")
        Fail(start, start.kind == Kind::kKey ? start.key : "META_START", "expected META_START");
      const auto kv = Block("META", meta_keys);
      for (const char* k : {"OBJECT_NAME", "OBJECT_ID", "REF_FRAME_A", "REF_FRAME_B", "TIME_SYSTEM", "START_TIME",
                            "STOP_TIME", "ATTITUDE_TYPE"})
        Need(kv, k, start);
      SetTimeSystem(*kv.at("TIME_SYSTEM"));
      h_.object_name = kv.at("OBJECT_NAME")->value;
      h_.object_id = kv.at("OBJECT_ID")->value;
      int dir = Direction(*kv.at("REF_FRAME_A"), *kv.at("REF_FRAME_B"));
      const Item& type_item = *kv.at("ATTITUDE_TYPE");
      const std::string type = Upper(type_item.value);
      const bool v1 = h_.version == "1.0";
      int n_rate = 0;  // values after the quaternion
      bool angvel = false;
      if (type == "QUATERNION") {
      } else if (type == "QUATERNION/ANGVEL" && !v1) {
        n_rate = 3, angvel = true;
      } else if (type == "QUATERNION/DERIVATIVE" || (type == "QUATERNION/RATE" && v1)) {
        n_rate = type == "QUATERNION/DERIVATIVE" ? 4 : 3;
      } else {
        Fail(type_item, "ATTITUDE_TYPE", "'" + type_item.value + "' is not read (ssiu reads quaternion attitudes)");
      }
      bool scalar_first = false;
      if (v1) {  // ADM 1.0 (504.0-B-1): QUATERNION_TYPE FIRST/LAST and ATTITUDE_DIR A2B/B2A
        const Item& qt = *Need(kv, "QUATERNION_TYPE", start);
        if (Upper(qt.value) != "FIRST" && Upper(qt.value) != "LAST")
          Fail(qt, "QUATERNION_TYPE", "'" + qt.value + "' (FIRST or LAST)");
        scalar_first = Upper(qt.value) == "FIRST";
        const Item& ad = *Need(kv, "ATTITUDE_DIR", start);
        if (Upper(ad.value) != "A2B" && Upper(ad.value) != "B2A")
          Fail(ad, "ATTITUDE_DIR", "'" + ad.value + "' (A2B or B2A)");
        if (Upper(ad.value) == "B2A") dir = -dir;
        if (kv.count("EULER_ROT_SEQ"))
          Fail(*kv.at("EULER_ROT_SEQ"), "EULER_ROT_SEQ", "given for a quaternion attitude");
        if (kv.count("RATE_FRAME") && type == "QUATERNION")
          Fail(*kv.at("RATE_FRAME"), "RATE_FRAME", "given without rates");
      } else if (kv.count("QUATERNION_TYPE") || kv.count("ATTITUDE_DIR")) {
        const Item& x = *kv.at(kv.count("QUATERNION_TYPE") ? "QUATERNION_TYPE" : "ATTITUDE_DIR");
        Fail(x, x.key, "an ADM 1.0 keyword in a version 2.0 message");
      }
      // ANGVEL_FRAME (sec. 4.2.3) names a frame, or REF_FRAME_A / REF_FRAME_B; absent = REF_FRAME_B.
      bool rate_in_inertial = false;
      if (angvel) {
        std::string f = kv.count("ANGVEL_FRAME") ? kv.at("ANGVEL_FRAME")->value : "REF_FRAME_B";
        if (Upper(f) == "REF_FRAME_A") f = kv.at("REF_FRAME_A")->value;
        if (Upper(f) == "REF_FRAME_B") f = kv.at("REF_FRAME_B")->value;
        if (f != h_.body_frame && f != h_.inertial_frame)
          Fail(*kv.at("ANGVEL_FRAME"), "ANGVEL_FRAME",
               "'" + f + "' is neither " + h_.body_frame + " nor " + h_.inertial_frame);
        rate_in_inertial = f == h_.inertial_frame;
      }
      if (Done() || Cur().kind != Kind::kStart || Cur().key != "DATA")
        Done() ? FailEnd("DATA_START", "missing after META_STOP")
               : Fail(Cur(), "DATA_START", "missing after META_STOP");
      std::vector<const Item*> data;
      Block("DATA", {"COMMENT"}, &data);
      const size_t first_of_segment = h_.states.size();
      for (const Item* d : data) {
        std::istringstream is(d->value);
        std::string epoch;
        is >> epoch;
        std::string rest;
        std::getline(is, rest);
        const std::vector<double> v = Numbers(*d, "DATA", rest);
        if (v.size() != static_cast<size_t>(4 + n_rate))
          Fail(*d, "ATTITUDE_TYPE",
               type + " needs " + std::to_string(5 + n_rate) + " fields per line, found " +
                   std::to_string(v.size() + 1));
        AdmState s;
        s.t_s = Epoch(*d, "EPOCH", epoch);
        s.q_inertial_from_body = scalar_first ? ToQuat(*d, "DATA", v[1], v[2], v[3], v[0], dir)
                                              : ToQuat(*d, "DATA", v[0], v[1], v[2], v[3], dir);
        if (angvel) {
          // The rate of REF_FRAME_B relative to REF_FRAME_A: to body axes, then body relative to inertial.
          Vec3 w = Vec3(v[4], v[5], v[6]) * kDegToRad;
          if (rate_in_inertial) w = s.q_inertial_from_body.conjugate() * w;
          s.w_body_rad_s = dir > 0 ? w : Vec3(-w);
        }
        // Segments may share their boundary epoch (one ends where the next starts): kept once.
        if (h_.states.size() == first_of_segment && first_of_segment > 0 &&
            std::abs(s.t_s - h_.states.back().t_s) < 1e-9)
          continue;
        Add(*d, s);
      }
      ++segments;
    }
    if (segments == 0) FailEnd("META_START", "no segment");
  }

  void Add(const Item& it, const AdmState& s) {
    if (!h_.states.empty() && !(s.t_s > h_.states.back().t_s)) Fail(it, "EPOCH", "times do not increase");
    h_.states.push_back(s);
  }

  void Acm() {
    static const std::set<std::string> meta_keys = {"COMMENT",
                                                    "OBJECT_NAME",
                                                    "INTERNATIONAL_DESIGNATOR",
                                                    "CATALOG_NAME",
                                                    "OBJECT_DESIGNATOR",
                                                    "ORIGINATOR_POC",
                                                    "ORIGINATOR_POSITION",
                                                    "ORIGINATOR_PHONE",
                                                    "ORIGINATOR_EMAIL",
                                                    "ORIGINATOR_ADDRESS",
                                                    "ODM_MSG_LINK",
                                                    "CENTER_NAME",
                                                    "TIME_SYSTEM",
                                                    "EPOCH_TZERO",
                                                    "ACM_DATA_ELEMENTS",
                                                    "START_TIME",
                                                    "STOP_TIME",
                                                    "TAIMUTC_AT_TZERO",
                                                    "NEXT_LEAP_EPOCH",
                                                    "NEXT_LEAP_TAIMUTC"};
    static const std::set<std::string> att_keys = {"COMMENT",      "ATT_ID",        "ATT_PREV_ID", "ATT_BASIS",
                                                   "ATT_BASIS_ID", "REF_FRAME_A",   "REF_FRAME_B", "NUMBER_STATES",
                                                   "ATT_TYPE",     "EULER_ROT_SEQ", "RATE_TYPE"};
    static const std::set<std::string> cov_keys = {"COMMENT",      "COV_ID",        "COV_PREV_ID", "COV_BASIS",
                                                   "COV_BASIS_ID", "COV_REF_FRAME", "COV_TYPE"};
    static const std::set<std::string> ad_keys = {
        "COMMENT",       "AD_ID",           "AD_PREV_ID",    "AD_METHOD", "ATTITUDE_SOURCE",
        "NUMBER_STATES", "ATTITUDE_STATES", "EULER_ROT_SEQ", "COV_TYPE",  "REF_FRAME_A",
        "REF_FRAME_B",   "RATE_STATES",     "SIGMA_U",       "SIGMA_V",   "RATE_PROCESS_NOISE_STDDEV"};
    if (Done() || Cur().kind != Kind::kStart || Cur().key != "META")
      Done() ? FailEnd("META_START", "missing") : Fail(Cur(), "META_START", "expected after the header");
    const Item& meta_start = Cur();
    const auto meta = Block("META", meta_keys);
    for (const char* k : {"OBJECT_NAME", "TIME_SYSTEM", "EPOCH_TZERO"}) Need(meta, k, meta_start);
    SetTimeSystem(*meta.at("TIME_SYSTEM"));
    h_.object_name = meta.at("OBJECT_NAME")->value;
    const Item& tzero = *meta.at("EPOCH_TZERO");
    const double t0 = Epoch(tzero, "EPOCH_TZERO", tzero.value);  // data lines are seconds after EPOCH_TZERO
    bool have_att = false;
    std::vector<std::pair<const Item*, std::map<std::string, const Item*>>> covs;
    std::vector<std::vector<const Item*>> cov_data;
    while (!Done()) {
      const Item& start = Cur();
      if (start.kind != Kind::kStart) Fail(start, start.kind == Kind::kKey ? start.key : "DATA", "outside a section");
      if (start.key == "ATT") {
        std::vector<const Item*> data;
        const auto kv = Block("ATT", att_keys, &data);
        for (const char* k : {"REF_FRAME_A", "REF_FRAME_B", "NUMBER_STATES", "ATT_TYPE"}) Need(kv, k, start);
        if (Upper(kv.at("ATT_TYPE")->value) != "QUATERNION") continue;  // other representations: skipped
        // The first quaternion block; a later one at the same epochs adds its rate type (a block
        // holds one: angular velocity and gyro bias come in two).
        ReadAtt(start, kv, data, t0, have_att);
        have_att = true;
      } else if (start.key == "COV") {
        std::vector<const Item*> data;
        const auto kv = Block("COV", cov_keys, &data);
        Need(kv, "COV_TYPE", start);
        covs.push_back({&start, kv});
        cov_data.push_back(data);
      } else if (start.key == "AD") {
        std::vector<std::map<std::string, const Item*>> sensors;
        const auto kv = Block("AD", ad_keys, nullptr, &sensors);
        ReadAd(start, kv, sensors);
      } else if (start.key == "PHYS" || start.key == "MAN" || start.key == "USER") {
        Block(start.key, {});  // not an attitude: skipped
      } else {
        Fail(start, start.key + "_START", "not an ACM section");
      }
    }
    if (!have_att) FailEnd("ATT_TYPE", "no ATT section with ATT_TYPE = QUATERNION (ssiu reads quaternion attitudes)");
    for (size_t i = 0; i < covs.size(); ++i) ReadCov(*covs[i].first, covs[i].second, cov_data[i], t0);
  }

  void ReadAtt(const Item& start, const std::map<std::string, const Item*>& kv, const std::vector<const Item*>& data,
               double t0, bool merge) {
    if (merge) {
      const Item& a = *kv.at("REF_FRAME_A");
      const Item& b = *kv.at("REF_FRAME_B");
      if (a.value + b.value != h_.inertial_frame + h_.body_frame || data.size() != h_.states.size()) return;
      for (size_t k = 0; k < data.size(); ++k) {
        const std::vector<double> v = Numbers(*data[k], "ATT", data[k]->value);
        if (v.empty() || std::abs(t0 + v[0] - h_.states[k].t_s) > 1e-9) return;
      }
    }
    const std::vector<AdmState> before = h_.states;
    if (merge) h_.states.clear();
    const int dir = Direction(*kv.at("REF_FRAME_A"), *kv.at("REF_FRAME_B"));
    const Item& ns = *kv.at("NUMBER_STATES");
    const double n_states = Number(ns, "NUMBER_STATES", ns.value);
    const std::string rate = Upper(Get(kv, "RATE_TYPE"));
    int expect = 4;
    if (rate == "ANGVEL" || rate == "GYRO_BIAS" || rate == "EULER_RATE")
      expect = 7;
    else if (rate == "Q_DOT")
      expect = 8;
    else if (!rate.empty() && rate != "NONE")
      Fail(*kv.at("RATE_TYPE"), "RATE_TYPE", "'" + rate + "' is not an ACM rate type");
    if (n_states != expect)
      Fail(ns, "NUMBER_STATES",
           ns.value + " for QUATERNION" + (rate.empty() ? "" : " and " + rate) + " (expected " +
               std::to_string(expect) + ")");
    if (kv.count("ATT_BASIS")) h_.basis = kv.at("ATT_BASIS")->value;
    if (data.empty()) Fail(start, "ATT_START", "no data lines");
    for (const Item* d : data) {
      const std::vector<double> v = Numbers(*d, "ATT", d->value);
      if (v.size() != static_cast<size_t>(1 + expect))
        Fail(*d, "NUMBER_STATES", "line has " + std::to_string(v.size() - 1) + " states, NUMBER_STATES is " + ns.value);
      AdmState s;
      s.t_s = t0 + v[0];
      s.q_inertial_from_body = ToQuat(*d, "ATT", v[1], v[2], v[3], v[4], dir);
      if (rate == "ANGVEL" || rate == "GYRO_BIAS") {
        Vec3 w = Vec3(v[5], v[6], v[7]) * kDegToRad;
        if (rate == "ANGVEL") {
          if (dir < 0) w = -(s.q_inertial_from_body.conjugate() * w);
          s.w_body_rad_s = w;
        } else {
          s.gyro_bias_rad_s = w;
        }
      }
      if (merge) {  // keep the first block's attitude, take this block's rate states
        const AdmState& p = before[h_.states.size()];
        s.q_inertial_from_body = p.q_inertial_from_body;
        if (!s.w_body_rad_s) s.w_body_rad_s = p.w_body_rad_s;
        if (!s.gyro_bias_rad_s) s.gyro_bias_rad_s = p.gyro_bias_rad_s;
      }
      Add(*d, s);
    }
  }

  void ReadCov(const Item& start, const std::map<std::string, const Item*>& kv, const std::vector<const Item*>& data,
               double t0) {
    const Item& ct = *kv.at("COV_TYPE");
    const std::string type = Upper(ct.value);
    static const std::map<std::string, int> sizes = {
        {"ANGLE", 3},      {"ANGLE_GYROBIAS", 6},      {"ANGLE_ANGVEL", 6},
        {"QUATERNION", 4}, {"QUATERNION_GYROBIAS", 7}, {"QUATERNION_ANGVEL", 7}};
    const auto n = sizes.find(type);
    if (n == sizes.end()) Fail(ct, "COV_TYPE", "'" + ct.value + "' is not an ACM covariance type");
    if (data.empty()) Fail(start, "COV_START", "no data lines");
    std::vector<AdmCovariance> rows;
    for (const Item* d : data) {
      const std::vector<double> v = Numbers(*d, "COV", d->value);
      if (v.size() != static_cast<size_t>(1 + n->second))
        Fail(*d, "COV_TYPE",
             type + " needs " + std::to_string(n->second) + " values per line, found " + std::to_string(v.size() - 1));
      AdmCovariance c;
      c.t_s = t0 + v[0];
      for (size_t i = 1; i < v.size(); ++i) {
        if (v[i] < 0) Fail(*d, "COV", "negative variance");
        c.diagonal.push_back(v[i] * kDegToRad * kDegToRad);
      }
      rows.push_back(c);
    }
    const std::string frame = Get(kv, "COV_REF_FRAME");
    // Kept: the first ANGLE or ANGLE_GYROBIAS block in the attitude's body frame (ssiu's covariance).
    if ((type == "ANGLE" || type == "ANGLE_GYROBIAS") && h_.covariances.empty() &&
        (frame.empty() || frame == h_.body_frame)) {
      h_.cov_type = type;
      h_.covariances = std::move(rows);
    }
  }

  void ReadAd(const Item& start, const std::map<std::string, const Item*>& kv,
              const std::vector<std::map<std::string, const Item*>>& sensors) {
    Need(kv, "ATTITUDE_STATES", start);
    Need(kv, "REF_FRAME_A", start);
    Need(kv, "REF_FRAME_B", start);
    AdmDetermination d;
    d.method = Get(kv, "AD_METHOD");
    d.source = Get(kv, "ATTITUDE_SOURCE");
    if (kv.count("SIGMA_U"))
      d.sigma_u_rad_s15 = Number(*kv.at("SIGMA_U"), "SIGMA_U", kv.at("SIGMA_U")->value) * kDegToRad;
    if (kv.count("SIGMA_V"))
      d.sigma_v_rad_s05 = Number(*kv.at("SIGMA_V"), "SIGMA_V", kv.at("SIGMA_V")->value) * kDegToRad;
    std::set<int> numbers;
    for (const auto& s : sensors) {
      AdmSensor a;
      const auto num = s.find("SENSOR_NUMBER");
      if (num == s.end()) Fail(start, "SENSOR_NUMBER", "missing in a SENSOR section");
      a.number = static_cast<int>(Number(*num->second, "SENSOR_NUMBER", num->second->value));
      if (!numbers.insert(a.number).second) Fail(*num->second, "SENSOR_NUMBER", num->second->value + " used twice");
      if (s.count("SENSOR_USED")) a.used = s.at("SENSOR_USED")->value;
      if (s.count("SENSOR_NOISE_STDDEV")) {
        const Item& ns = *s.at("SENSOR_NOISE_STDDEV");
        for (double x : Numbers(ns, "SENSOR_NOISE_STDDEV", ns.value)) a.noise_sigma_rad.push_back(x * kDegToRad);
        if (s.count("NUMBER_SENSOR_NOISE_COVARIANCE")) {
          const Item& nn = *s.at("NUMBER_SENSOR_NOISE_COVARIANCE");
          if (Number(nn, nn.key, nn.value) != static_cast<double>(a.noise_sigma_rad.size()))
            Fail(ns, "SENSOR_NOISE_STDDEV",
                 std::to_string(a.noise_sigma_rad.size()) + " values, NUMBER_SENSOR_NOISE_COVARIANCE is " + nn.value);
        }
      }
      if (s.count("SENSOR_FREQUENCY")) {
        const Item& f = *s.at("SENSOR_FREQUENCY");
        a.rate_hz = Number(f, "SENSOR_FREQUENCY", f.value);
      }
      d.sensors.push_back(a);
    }
    h_.determination = d;
  }

  std::vector<Item> items_;
  std::string file_, epoch_;
  size_t pos_ = 0;
  bool frames_set_ = false;
  AttitudeHistory h_;
};

bool StartsXml(const std::string& text) {
  for (char c : text) {
    if (std::isspace(static_cast<unsigned char>(c)) || c == '\xEF' || c == '\xBB' || c == '\xBF') continue;
    return c == '<';
  }
  return false;
}

}  // namespace

AttitudeHistory ParseAdm(const std::string& text, const std::string& file, const std::string& epoch_utc) {
  std::vector<Item> items = StartsXml(text) ? LexXml(text, file) : LexKvn(text);
  return Parser(std::move(items), file, epoch_utc).Run();
}

AttitudeHistory ReadAdmFile(const std::string& path, const std::string& epoch_utc) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw InputError(path, "cannot open");
  std::ostringstream ss;
  ss << f.rdbuf();
  return ParseAdm(ss.str(), path, epoch_utc);
}

bool LooksLikeAdm(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  std::string head(256, '\0');
  f.read(&head[0], head.size());
  head.resize(static_cast<size_t>(f.gcount()));
  if (StartsXml(head)) return true;
  // Any CCSDS message (an OEM or OPM too): the ADM reader names what it is and refuses it in one line.
  return Trim(head).rfind("CCSDS_", 0) == 0;
}

}  // namespace ssiu
