// Writing AEM and ACM messages (504.0-B-2 sec. 4 AEM, sec. 5 ACM; XML per the NDM/XML 4.0.0 schemas,
// element order as the schema's sequences). KVN and XML take every number from the same formatting,
// so the two encodings of one history carry the same digits.
#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <sstream>

#include "ccsds/adm.h"
#include "core/error.h"
#include "core/output.h"

namespace ssiu {
namespace {

std::string Num(const char* fmt, double v) {
  char b[64];
  std::snprintf(b, sizeof b, fmt, v);
  return b;
}
// Printed precision: quaternion components 1e-12 (2e-7 arcsec), rates and covariances 10 significant
// digits, times 1 microsecond.
std::string Qc(double v) { return Num("%.12f", v); }
std::string Sci(double v) { return Num("%.10e", v); }
std::string Sec(double v) { return Num("%.6f", v); }

// ADM (Q1, Q2, Q3, QC) of q_inertial_from_body with REF_FRAME_A inertial, REF_FRAME_B body: the same
// components, scalar last (adm.h), scalar >= 0.
std::array<double, 4> AdmQuaternion(const Quat& q_in) {
  Quat q = q_in.normalized();
  if (q.w() < 0) q.coeffs() *= -1;
  return {q.x(), q.y(), q.z(), q.w()};
}

std::string NowUtc() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char b[32];
  std::strftime(b, sizeof b, "%Y-%m-%dT%H:%M:%S", &tm);
  return b;
}

std::string XmlEscape(const std::string& s) {
  std::string r;
  for (char c : s) {
    if (c == '&')
      r += "&amp;";
    else if (c == '<')
      r += "&lt;";
    else if (c == '>')
      r += "&gt;";
    else
      r += c;
  }
  return r;
}

// One writer, two encodings: a keyword/value pair is `KEY = value` or `<KEY>value</KEY>`; a block is
// `NAME_START`/`NAME_STOP` in KVN and an element in XML; a data line is raw text or `<tag>text</tag>`.
class Out {
 public:
  explicit Out(bool xml) : xml_(xml) {}
  void Kv(const std::string& key, const std::string& value, const std::string& units = "") {
    if (xml_) {
      os_ << Indent() << "<" << key;
      if (!units.empty()) os_ << " units=\"" << units << "\"";
      os_ << ">" << XmlEscape(value) << "</" << key << ">\n";
    } else {
      char b[64];
      std::snprintf(b, sizeof b, "%-30s = ", key.c_str());
      os_ << b << value << "\n";
    }
  }
  void Comment(const std::string& text) {
    if (xml_)
      Kv("COMMENT", text);
    else
      os_ << "COMMENT " << text << "\n";
  }
  // kvn: "META" -> META_START; xml: "metadata".
  void Open(const std::string& kvn, const std::string& xml) {
    if (xml_) {
      if (!xml.empty()) os_ << Indent() << "<" << xml << ">\n", ++depth_;
    } else if (!kvn.empty()) {
      os_ << kvn << "_START\n";
    }
  }
  void Close(const std::string& kvn, const std::string& xml) {
    if (xml_) {
      if (!xml.empty()) --depth_, os_ << Indent() << "</" << xml << ">\n";
    } else if (!kvn.empty()) {
      os_ << kvn << "_STOP\n";
    }
  }
  void Line(const std::string& xml_tag, const std::string& text) {
    if (xml_)
      os_ << Indent() << "<" << xml_tag << ">" << text << "</" << xml_tag << ">\n";
    else
      os_ << text << "\n";
  }
  void Raw(const std::string& s) { os_ << s; }
  void Blank() {
    if (!xml_) os_ << "\n";
  }
  bool xml() const { return xml_; }
  std::string str() const { return os_.str(); }
  int depth_ = 0;

 private:
  std::string Indent() const { return std::string(2 * depth_, ' '); }
  bool xml_;
  std::ostringstream os_;
};

void CheckWritable(const AttitudeHistory& h) {
  const std::string where = h.file.empty() ? "attitude history" : h.file;
  if (h.epoch_utc.empty()) throw InputError(where, "no epoch (UTC of t_s = 0): cannot write a CCSDS ADM");
  if (h.states.empty()) throw InputError(where, "no attitude to write");
  for (size_t k = 1; k < h.states.size(); ++k)
    if (!(h.states[k].t_s > h.states[k - 1].t_s))
      throw InputError(where, "times do not increase at state " + std::to_string(k + 1));
  for (const AdmCovariance& c : h.covariances) {
    const size_t n = h.cov_type == "ANGLE" ? 3 : 6;
    if (c.diagonal.size() != n)
      throw InputError(where, "covariance of " + h.cov_type + " needs " + std::to_string(n) + " values");
  }
}

void Header(Out& o, const AttitudeHistory& h, const std::string& kind, const std::string& creation) {
  if (o.xml()) {
    o.Raw("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
    o.Raw("<" + kind + " xmlns:xsi=\"http://www.w3.org/2001/XMLSchema-instance\" id=\"CCSDS_" +
          std::string(kind == "aem" ? "AEM" : "ACM") + "_VERS\" version=\"2.0\">\n");
    o.depth_ = 1;
    o.Open("", "header");
  } else {
    o.Kv(kind == "aem" ? "CCSDS_AEM_VERS" : "CCSDS_ACM_VERS", "2.0");
  }
  for (const std::string& c : h.comments) o.Comment(c);
  o.Kv("CREATION_DATE", creation);
  o.Kv("ORIGINATOR", "SSIU");
  o.Close("", "header");
  o.Blank();
  if (o.xml()) o.Open("", "body"), o.Open("", "segment");
}

void Footer(Out& o, const std::string& kind) {
  if (!o.xml()) return;
  o.Close("", "segment");
  o.Close("", "body");
  o.depth_ = 0;
  o.Raw("</" + kind + ">\n");
}

std::string FormatAem(const AttitudeHistory& h, bool xml, const std::string& creation) {
  Out o(xml);
  Header(o, h, "aem", creation);
  const bool rates = h.has_rates();
  o.Open("META", "metadata");
  o.Kv("OBJECT_NAME", h.object_name);
  o.Kv("OBJECT_ID", h.object_id);
  o.Kv("REF_FRAME_A", h.inertial_frame);
  o.Kv("REF_FRAME_B", h.body_frame);
  o.Kv("TIME_SYSTEM", "UTC");
  o.Kv("START_TIME", AdmEpoch(h.epoch_utc, h.states.front().t_s));
  o.Kv("STOP_TIME", AdmEpoch(h.epoch_utc, h.states.back().t_s));
  o.Kv("ATTITUDE_TYPE", rates ? "QUATERNION/ANGVEL" : "QUATERNION");
  if (rates) o.Kv("ANGVEL_FRAME", h.body_frame);  // sec. 4.2.3: the frame of the angular velocity
  o.Close("META", "metadata");
  o.Blank();
  o.Open("DATA", "data");
  for (const AdmState& s : h.states) {
    const auto q = AdmQuaternion(s.q_inertial_from_body);
    const std::string epoch = AdmEpoch(h.epoch_utc, s.t_s);
    Vec3 w_deg_s = rates ? Vec3(*s.w_body_rad_s * kRadToDeg) : Vec3::Zero();
    if (!xml) {
      std::string line = epoch + " " + Qc(q[0]) + " " + Qc(q[1]) + " " + Qc(q[2]) + " " + Qc(q[3]);
      if (rates) line += " " + Sci(w_deg_s.x()) + " " + Sci(w_deg_s.y()) + " " + Sci(w_deg_s.z());
      o.Raw(line + "\n");
      continue;
    }
    o.Open("", "attitudeState");
    o.Open("", rates ? "quaternionAngVel" : "quaternionEphemeris");
    o.Kv("EPOCH", epoch);
    o.Open("", "quaternion");
    o.Kv("Q1", Qc(q[0]));
    o.Kv("Q2", Qc(q[1]));
    o.Kv("Q3", Qc(q[2]));
    o.Kv("QC", Qc(q[3]));
    o.Close("", "quaternion");
    if (rates) {
      o.Open("", "angVel");
      o.Kv("ANGVEL_X", Sci(w_deg_s.x()), "deg/s");
      o.Kv("ANGVEL_Y", Sci(w_deg_s.y()), "deg/s");
      o.Kv("ANGVEL_Z", Sci(w_deg_s.z()), "deg/s");
      o.Close("", "angVel");
    }
    o.Close("", rates ? "quaternionAngVel" : "quaternionEphemeris");
    o.Close("", "attitudeState");
  }
  o.Close("DATA", "data");
  Footer(o, "aem");
  return o.str();
}

std::string Joined(const std::vector<std::string>& v, const std::string& sep) {
  std::string r;
  for (size_t i = 0; i < v.size(); ++i) r += (i ? sep : "") + v[i];
  return r;
}

std::string FormatAcm(const AttitudeHistory& h, bool xml, const std::string& creation) {
  Out o(xml);
  Header(o, h, "acm", creation);
  const bool rates = h.has_rates(), bias = h.has_bias();
  std::vector<std::string> elements = {"ATT"};
  if (!h.covariances.empty()) elements.push_back("COV");
  if (h.determination) elements.push_back("AD");
  o.Open("META", "metadata");
  o.Kv("OBJECT_NAME", h.object_name);
  o.Kv("TIME_SYSTEM", "UTC");
  o.Kv("EPOCH_TZERO", AdmEpoch(h.epoch_utc, 0.0));
  o.Kv("ACM_DATA_ELEMENTS", Joined(elements, ", "));
  o.Close("META", "metadata");
  o.Blank();
  if (xml) o.Open("", "data");
  // ATT (sec. 5.2.3): t, Q1 Q2 Q3 QC, then the rate states; one rate type per block, so angular
  // velocity and gyro bias each get a block when both are known.
  auto att = [&](const char* rate_type) {
    o.Open("ATT", "att");
    if (!h.basis.empty()) o.Kv("ATT_BASIS", h.basis);
    o.Kv("REF_FRAME_A", h.inertial_frame);
    o.Kv("REF_FRAME_B", h.body_frame);
    o.Kv("NUMBER_STATES", rate_type ? "7" : "4");
    o.Kv("ATT_TYPE", "QUATERNION");
    if (rate_type) o.Kv("RATE_TYPE", rate_type);
    const bool angvel = rate_type && std::string(rate_type) == "ANGVEL";
    for (const AdmState& s : h.states) {
      const auto q = AdmQuaternion(s.q_inertial_from_body);
      std::string line = Sec(s.t_s) + " " + Qc(q[0]) + " " + Qc(q[1]) + " " + Qc(q[2]) + " " + Qc(q[3]);
      if (rate_type) {
        const Vec3 v_deg_s = (angvel ? *s.w_body_rad_s : *s.gyro_bias_rad_s) * kRadToDeg;
        line += " " + Sci(v_deg_s.x()) + " " + Sci(v_deg_s.y()) + " " + Sci(v_deg_s.z());
      }
      o.Line("attLine", line);
    }
    o.Close("ATT", "att");
    o.Blank();
  };
  if (rates) att("ANGVEL");
  if (bias) att("GYRO_BIAS");
  if (!rates && !bias) att(nullptr);
  if (!h.covariances.empty()) {  // COV (sec. 5.2.5): the diagonal, deg^2 and (deg/s)^2
    o.Open("COV", "cov");
    if (!h.basis.empty()) o.Kv("COV_BASIS", h.basis);
    o.Kv("COV_REF_FRAME", h.body_frame);
    o.Kv("COV_TYPE", h.cov_type);
    for (const AdmCovariance& c : h.covariances) {
      std::string line = Sec(c.t_s);
      for (double v : c.diagonal) line += " " + Sci(v * kRadToDeg * kRadToDeg);
      o.Line("covLine", line);
    }
    o.Close("COV", "cov");
    o.Blank();
  }
  if (h.determination) {  // AD (sec. 5.2.7)
    const AdmDetermination& d = *h.determination;
    o.Open("AD", "ad");
    o.Kv("AD_METHOD", d.method);
    o.Kv("ATTITUDE_SOURCE", d.source);
    o.Kv("NUMBER_STATES", bias ? "7" : "4");
    o.Kv("ATTITUDE_STATES", "QUATERNION");
    if (!h.cov_type.empty()) o.Kv("COV_TYPE", h.cov_type);
    o.Kv("REF_FRAME_A", h.inertial_frame);
    o.Kv("REF_FRAME_B", h.body_frame);
    if (bias) o.Kv("RATE_STATES", "GYRO_BIAS");
    if (d.sigma_u_rad_s15 >= 0) o.Kv("SIGMA_U", Sci(d.sigma_u_rad_s15 * kRadToDeg), xml ? "deg/s**1.5" : "");
    if (d.sigma_v_rad_s05 >= 0) o.Kv("SIGMA_V", Sci(d.sigma_v_rad_s05 * kRadToDeg), xml ? "deg/s**0.5" : "");
    for (const AdmSensor& s : d.sensors) {
      o.Open("SENSOR", "sensorData");
      o.Kv("SENSOR_NUMBER", std::to_string(s.number));
      o.Kv("SENSOR_USED", s.used);
      if (!s.noise_sigma_rad.empty()) {
        std::vector<std::string> v;
        for (double x : s.noise_sigma_rad) v.push_back(Sci(x * kRadToDeg));
        o.Kv("NUMBER_SENSOR_NOISE_COVARIANCE", std::to_string(v.size()));
        o.Kv("SENSOR_NOISE_STDDEV", Joined(v, " "), xml ? "deg" : "");
      }
      if (s.rate_hz > 0) o.Kv("SENSOR_FREQUENCY", Sci(s.rate_hz), xml ? "Hz" : "");
      o.Close("SENSOR", "sensorData");
    }
    o.Close("AD", "ad");
  }
  if (xml) o.Close("", "data");
  Footer(o, "acm");
  return o.str();
}

}  // namespace

bool AttitudeHistory::has_rates() const {
  return !states.empty() &&
         std::all_of(states.begin(), states.end(), [](const AdmState& s) { return s.w_body_rad_s.has_value(); });
}
bool AttitudeHistory::has_bias() const {
  return !states.empty() &&
         std::all_of(states.begin(), states.end(), [](const AdmState& s) { return s.gyro_bias_rad_s.has_value(); });
}

std::string FormatAdm(const AttitudeHistory& h, AdmMessage message, bool xml, const std::string& creation_utc) {
  CheckWritable(h);
  const std::string creation = creation_utc.empty() ? NowUtc() : creation_utc;
  return message == AdmMessage::kAem ? FormatAem(h, xml, creation) : FormatAcm(h, xml, creation);
}

void WriteAdmFile(const std::string& path, const AttitudeHistory& h, AdmMessage message) {
  std::string lower = path;
  std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char c) { return std::tolower(c); });
  const bool xml = lower.size() >= 4 && lower.compare(lower.size() - 4, 4, ".xml") == 0;
  AttitudeHistory named = h;
  if (named.file.empty()) named.file = path;
  WriteFileAtomic(path, FormatAdm(named, message, xml));
}

}  // namespace ssiu
