#include "structgp/io/model_file.h"

#include <zlib.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>
#include <string>
#include <tuple>
#include <utility>

#include "structgp/io/atomic_file.h"
#include "structgp/model/weight_space_gp.h"

namespace structgp {
namespace {

using Json = nlohmann::json;

constexpr const char* kEncoding = "base64-f64le";
constexpr const char* kColumnMajor = "column_major";
constexpr const char* kUpperTriangular = "upper_triangular";
constexpr const char* kBase64Alphabet =
    "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

// ---- encoding -------------------------------------------------------------------------------

std::string Base64Encode(const std::string& bytes) {
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  size_t i = 0;
  for (; i + 2 < bytes.size(); i += 3) {
    const uint32_t v = (uint32_t{static_cast<unsigned char>(bytes[i])} << 16) |
                       (uint32_t{static_cast<unsigned char>(bytes[i + 1])} << 8) |
                       uint32_t{static_cast<unsigned char>(bytes[i + 2])};
    out += kBase64Alphabet[(v >> 18) & 63];
    out += kBase64Alphabet[(v >> 12) & 63];
    out += kBase64Alphabet[(v >> 6) & 63];
    out += kBase64Alphabet[v & 63];
  }
  const size_t rest = bytes.size() - i;
  if (rest > 0) {
    uint32_t v = uint32_t{static_cast<unsigned char>(bytes[i])} << 16;
    if (rest == 2) v |= uint32_t{static_cast<unsigned char>(bytes[i + 1])} << 8;
    out += kBase64Alphabet[(v >> 18) & 63];
    out += kBase64Alphabet[(v >> 12) & 63];
    out += rest == 2 ? kBase64Alphabet[(v >> 6) & 63] : '=';
    out += '=';
  }
  return out;
}

int Base64Value(char c) {
  if (c >= 'A' && c <= 'Z') return c - 'A';
  if (c >= 'a' && c <= 'z') return c - 'a' + 26;
  if (c >= '0' && c <= '9') return c - '0' + 52;
  if (c == '+') return 62;
  if (c == '/') return 63;
  return -1;
}

// Strict decoder: length a multiple of 4, '=' padding only at the end. False on bad input.
bool Base64Decode(const std::string& text, std::string* bytes) {
  bytes->clear();
  if (text.size() % 4 != 0) return false;
  bytes->reserve(text.size() / 4 * 3);
  for (size_t i = 0; i < text.size(); i += 4) {
    const bool last = i + 4 == text.size();
    int pad = 0;
    uint32_t v = 0;
    for (size_t k = 0; k < 4; ++k) {
      const char c = text[i + k];
      int d = 0;
      if (c == '=' && last && k >= 2) {
        ++pad;
      } else {
        if (pad > 0) return false;  // data after padding
        d = Base64Value(c);
        if (d < 0) return false;
      }
      v = (v << 6) | static_cast<uint32_t>(d);
    }
    bytes->push_back(static_cast<char>((v >> 16) & 0xff));
    if (pad < 2) bytes->push_back(static_cast<char>((v >> 8) & 0xff));
    if (pad < 1) bytes->push_back(static_cast<char>(v & 0xff));
  }
  return true;
}

void AppendDouble(double value, std::string* bytes) {
  uint64_t bits = 0;
  std::memcpy(&bits, &value, sizeof(bits));
  for (int b = 0; b < 8; ++b) bytes->push_back(static_cast<char>((bits >> (8 * b)) & 0xff));
}

double ReadDouble(const std::string& bytes, size_t offset) {
  uint64_t bits = 0;
  for (int b = 0; b < 8; ++b) {
    bits |= uint64_t{static_cast<unsigned char>(bytes[offset + static_cast<size_t>(b)])} << (8 * b);
  }
  double value = 0.0;
  std::memcpy(&value, &bits, sizeof(value));
  return value;
}

Json EncodeMatrix(const Matrix& a, bool upper_triangular) {
  std::string bytes;
  bytes.reserve(static_cast<size_t>(a.size()) * 8);
  for (Eigen::Index j = 0; j < a.cols(); ++j) {
    const Eigen::Index rows = upper_triangular ? std::min<Eigen::Index>(j + 1, a.rows()) : a.rows();
    for (Eigen::Index i = 0; i < rows; ++i) AppendDouble(a(i, j), &bytes);
  }
  Json out;
  out["rows"] = a.rows();
  out["cols"] = a.cols();
  out["layout"] = upper_triangular ? kUpperTriangular : kColumnMajor;
  out["encoding"] = kEncoding;
  out["data"] = Base64Encode(bytes);
  return out;
}

Json NumberArray(const Vector& v) {
  Json out = Json::array();
  for (Eigen::Index i = 0; i < v.size(); ++i) out.push_back(v[i]);
  return out;
}

// zlib's CRC-32 of `size` bytes after `crc`; zlib takes the length as uInt, so large inputs go
// in pieces.
uLong Crc32Update(uLong crc, const char* data, size_t size) {
  constexpr size_t kPiece = size_t{1} << 30;
  for (size_t begin = 0; begin < size; begin += kPiece) {
    const size_t n = std::min(kPiece, size - begin);
    crc = crc32(crc, reinterpret_cast<const Bytef*>(data + begin), static_cast<uInt>(n));
  }
  return crc;
}

std::string Crc32Text(const std::string& text) {
  const uLong crc = Crc32Update(crc32(0L, Z_NULL, 0), text.data(), text.size());
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "crc32:%08lx", static_cast<unsigned long>(crc));
  return buffer;
}

// The checksum covers the compact text of the object without its "checksum" field. nlohmann
// writes numbers with the shortest text that reads back to the same value and keeps object
// keys sorted, so parsing a file and dumping it again gives the same text.
std::string Checksum(Json object) {
  object.erase("checksum");
  return Crc32Text(object.dump());
}

void RequireFiniteForSave(const std::string& what, const Eigen::Ref<const Matrix>& a) {
  if (!a.allFinite()) {
    throw std::invalid_argument("SaveModel: " + what + " holds a non-finite value");
  }
}

Form ParseForm(const std::string& text, bool* ok) {
  *ok = true;
  if (text == ToString(Form::kAuto)) return Form::kAuto;
  if (text == ToString(Form::kWeightSpace)) return Form::kWeightSpace;
  if (text == ToString(Form::kFunctionSpace)) return Form::kFunctionSpace;
  if (text == ToString(Form::kRegressor)) return Form::kRegressor;
  if (text == ToString(Form::kEulerLagrange)) return Form::kEulerLagrange;
  *ok = false;
  return Form::kAuto;
}

// "pol+fri + coulomb@2" for messages.
std::string Label(const ModelSpec& spec) {
  return ToString(spec) + (spec.effects.empty() ? "" : " + " + ToString(spec.effects));
}

// ---- decoding with messages that name the file and the field --------------------------------

class FieldReader {
 public:
  explicit FieldReader(std::string path) : path_(std::move(path)) {}

  [[noreturn]] void Fail(const std::string& message) const {
    throw DataError(path_, 0, 0, message);
  }
  [[noreturn]] void FailField(const std::string& field, const std::string& message) const {
    Fail("field '" + field + "': " + message);
  }

  const Json& Get(const Json& object, const std::string& prefix, const char* key) const {
    const std::string field = prefix.empty() ? key : prefix + "." + key;
    if (!object.is_object()) FailField(prefix, "expected an object");
    const auto it = object.find(key);
    if (it == object.end()) Fail("missing field '" + field + "'");
    return *it;
  }

  double Number(const Json& object, const std::string& prefix, const char* key) const {
    const Json& v = Get(object, prefix, key);
    if (!v.is_number()) FailField(Name(prefix, key), "expected a number, got " + Brief(v));
    const double x = v.get<double>();
    if (!std::isfinite(x)) FailField(Name(prefix, key), "expected a finite number");
    return x;
  }

  long long Integer(const Json& object, const std::string& prefix, const char* key, long long lo,
                    long long hi) const {
    const Json& v = Get(object, prefix, key);
    if (!v.is_number_integer()) {
      FailField(Name(prefix, key), "expected an integer, got " + Brief(v));
    }
    const long long x = v.get<long long>();
    if (x < lo || x > hi) {
      FailField(Name(prefix, key), "expected a value in " + std::to_string(lo) + ".." +
                                       std::to_string(hi) + ", got " + std::to_string(x));
    }
    return x;
  }

  bool Boolean(const Json& object, const std::string& prefix, const char* key) const {
    const Json& v = Get(object, prefix, key);
    if (!v.is_boolean()) FailField(Name(prefix, key), "expected true or false, got " + Brief(v));
    return v.get<bool>();
  }

  std::string String(const Json& object, const std::string& prefix, const char* key) const {
    const Json& v = Get(object, prefix, key);
    if (!v.is_string()) FailField(Name(prefix, key), "expected a string, got " + Brief(v));
    return v.get<std::string>();
  }

  Vector Numbers(const Json& object, const std::string& prefix, const char* key) const {
    const Json& v = Get(object, prefix, key);
    if (!v.is_array()) FailField(Name(prefix, key), "expected an array of numbers");
    Vector out(static_cast<Eigen::Index>(v.size()));
    for (size_t i = 0; i < v.size(); ++i) {
      if (!v[i].is_number() || !std::isfinite(v[i].get<double>())) {
        FailField(Name(prefix, key), "entry " + std::to_string(i + 1) + " is not a finite number");
      }
      out[static_cast<Eigen::Index>(i)] = v[i].get<double>();
    }
    return out;
  }

  Matrix DecodedMatrix(const Json& object, const std::string& prefix, const char* key) const {
    const std::string field = Name(prefix, key);
    const Json& m = Get(object, prefix, key);
    constexpr long long kMaxDim = 1LL << 26;
    const auto rows = static_cast<Eigen::Index>(Integer(m, field, "rows", 0, kMaxDim));
    const auto cols = static_cast<Eigen::Index>(Integer(m, field, "cols", 0, kMaxDim));
    const std::string layout = String(m, field, "layout");
    if (layout != kColumnMajor && layout != kUpperTriangular) {
      FailField(field, "unknown layout '" + layout + "' (expected '" + kColumnMajor + "' or '" +
                           kUpperTriangular + "')");
    }
    const bool upper = layout == kUpperTriangular;
    if (upper && rows != cols) FailField(field, "an upper-triangular matrix must be square");
    if (String(m, field, "encoding") != kEncoding) {
      FailField(field, std::string("unknown encoding (expected '") + kEncoding + "')");
    }
    std::string bytes;
    if (!Base64Decode(String(m, field, "data"), &bytes)) {
      FailField(field, "the data are not valid base64");
    }
    const size_t count = upper ? static_cast<size_t>(rows) * static_cast<size_t>(rows + 1) / 2
                               : static_cast<size_t>(rows) * static_cast<size_t>(cols);
    if (bytes.size() != 8 * count) {
      FailField(field, "expected " + std::to_string(count) + " doubles (" +
                           std::to_string(8 * count) + " bytes), the data hold " +
                           std::to_string(bytes.size()) + " bytes");
    }
    Matrix out = Matrix::Zero(rows, cols);
    size_t offset = 0;
    for (Eigen::Index j = 0; j < cols; ++j) {
      const Eigen::Index n = upper ? j + 1 : rows;
      for (Eigen::Index i = 0; i < n; ++i, offset += 8) out(i, j) = ReadDouble(bytes, offset);
    }
    if (!out.allFinite()) FailField(field, "holds a non-finite value");
    return out;
  }

  Vector DecodedVector(const Json& object, const std::string& prefix, const char* key) const {
    const Matrix m = DecodedMatrix(object, prefix, key);
    if (m.cols() != 1) FailField(Name(prefix, key), "expected a single column");
    return m.col(0);
  }

  static std::string Name(const std::string& prefix, const char* key) {
    return prefix.empty() ? std::string(key) : prefix + "." + key;
  }

 private:
  static std::string Brief(const Json& v) {
    std::string text = v.dump();
    if (text.size() > 40) text = text.substr(0, 37) + "...";
    return text;
  }

  std::string path_;
};

// 1-based line and column of byte `offset` (0-based) of `text`; columns count UTF-8 code points.
std::pair<int, int> LineAndColumn(const std::string& text, size_t offset) {
  offset = std::min(offset, text.size());
  int line = 1;
  int column = 1;
  for (size_t i = 0; i < offset; ++i) {
    const auto c = static_cast<unsigned char>(text[i]);
    if (c == '\n') {
      ++line;
      column = 1;
    } else if ((c & 0xC0) != 0x80) {
      ++column;
    }
  }
  return {line, column};
}

Json ParseJson(const std::string& text, const std::string& path) {
  if (text.find_first_not_of(" \t\r\n") == std::string::npos) {
    throw DataError(path, 0, 0, "not a structgp model file: the file is empty");
  }
  try {
    return Json::parse(text);
  } catch (const Json::parse_error& e) {
    // e.byte is the 1-based index of the byte where parsing stopped.
    const size_t offset = e.byte > 0 ? e.byte - 1 : 0;
    const auto [line, column] = LineAndColumn(text, offset);
    std::string reason = e.what();
    const size_t syntax = reason.find("syntax error");
    if (syntax != std::string::npos) reason = reason.substr(syntax);
    // The parser quotes the token it last read, which can be a whole base64 payload.
    constexpr size_t kMaxQuoted = 24;
    const size_t last = reason.find("; last read: '");
    if (last != std::string::npos && reason.size() > last + 14 + kMaxQuoted + 1) {
      reason = reason.substr(0, last + 14 + kMaxQuoted) + "...'";
    }
    const bool at_end = offset + 1 >= text.size();
    throw DataError(path, line, column,
                    std::string(at_end ? "truncated model file" : "malformed model file") +
                        " (not valid JSON): " + reason);
  } catch (const Json::exception& e) {
    // Valid JSON syntax the parser cannot hold, e.g. a number beyond the range of a double
    // ("number overflow parsing '1e999'"): no byte position, so the quoted token is located.
    std::string reason = e.what();
    const size_t bracket = reason.find("] ");
    if (bracket != std::string::npos) reason = reason.substr(bracket + 2);
    int line = 0;
    int column = 0;
    const size_t open = reason.find('\'');
    const size_t close = open == std::string::npos ? open : reason.find('\'', open + 1);
    if (close != std::string::npos) {
      const size_t at = text.find(reason.substr(open + 1, close - open - 1));
      if (at != std::string::npos) std::tie(line, column) = LineAndColumn(text, at);
    }
    constexpr size_t kMaxReason = 120;
    if (reason.size() > kMaxReason) reason = reason.substr(0, kMaxReason) + "...";
    throw DataError(path, line, column, "malformed model file (not valid JSON): " + reason);
  }
}

// One set of hyper-parameters as the file keeps it: a kernel's parameters (Hyperparameters::
// shape of a kernel model) in "kernel_parameters" and an empty "shape", as it always has.
Json HyperparametersJson(const Hyperparameters& h, bool kernel_model, const std::string& what) {
  RequireFiniteForSave(what + ".shape", h.shape);
  RequireFiniteForSave(what + ".log_block_scale", h.log_block_scale);
  RequireFiniteForSave(what + ".log_output_scale", h.log_output_scale);
  if (!std::isfinite(h.log_noise_std)) {
    throw std::invalid_argument("SaveModel: " + what + ".log_noise_std is not finite");
  }
  Json hyper;
  hyper["shape"] = NumberArray(kernel_model ? Vector() : h.shape);
  hyper["log_block_scale"] = NumberArray(h.log_block_scale);
  hyper["log_noise_std"] = h.log_noise_std;
  hyper["log_output_scale"] = NumberArray(h.log_output_scale);
  hyper["kernel_parameters"] = NumberArray(kernel_model ? h.shape : Vector());
  return hyper;
}

Json WeightSpaceJson(const WeightSpaceGPState& s) {
  RequireFiniteForSave("weight-space state", s.covariance_factor);
  RequireFiniteForSave("weight-space state", s.weights);
  Json w;
  w["prior_variance"] = EncodeMatrix(s.prior_variance, false);
  w["noise_variance"] = s.noise_variance;
  w["output_scales"] = EncodeMatrix(s.output_scales, false);
  w["covariance_factor"] = EncodeMatrix(s.covariance_factor, true);
  w["weights"] = EncodeMatrix(s.weights, false);
  w["y_squared"] = EncodeMatrix(s.y_squared, false);
  w["weight_sum"] = s.weight_sum;
  w["log_weight_sum"] = s.log_weight_sum;
  w["log_prior_broadening"] = s.log_prior_broadening;
  w["sample_count"] = s.sample_count;
  w["num_samples"] = s.num_samples;
  return w;
}

Json FunctionSpaceJson(const Matrix& inputs, const Matrix& targets) {
  RequireFiniteForSave("stored inputs", inputs);
  RequireFiniteForSave("stored targets", targets);
  Json f;
  f["inputs"] = EncodeMatrix(inputs, false);
  f["targets"] = EncodeMatrix(targets, false);
  return f;
}

}  // namespace

// ---- saving ---------------------------------------------------------------------------------

namespace {

// The model file's JSON object, its checksum included (ModelFileText, PosteriorFileBytes).
Json ModelFileJson(const RobotModel& model) {
  if (!model.fitted()) throw std::invalid_argument("SaveModel: the model is not fitted");
  const GaussianProcess& gp = model.gp();
  const Hyperparameters& h = model.hyperparameters();
  const bool kernel_model = model.kernel() != nullptr;
  Json hyper = HyperparametersJson(h, kernel_model, "hyperparameters");
  if (h.is_per_output()) {
    Json joints = Json::array();
    for (size_t j = 0; j < h.per_output.size(); ++j) {
      joints.push_back(HyperparametersJson(h.per_output[j], kernel_model,
                                           "hyperparameters.per_joint[" + std::to_string(j) + "]"));
    }
    hyper["per_joint"] = joints;
  }

  Json doc;
  doc["format"] = kModelFileFormat;
  // Models with shared hyper-parameters stay readable by builds that read version 2.
  // A calibrated model too needs a reader that applies its latent variance scale.
  const bool scaled = model.bands_calibrated();
  doc["version"] =
      h.is_per_output() || scaled ? kModelFileVersion : kSharedModelFileVersion;
  doc["model"] = ToString(model.spec());
  doc["effects"] = ToString(model.spec().effects);
  Json effects = Json::array();
  for (const EffectSpec& e : model.spec().effects) {
    Json item;
    item["name"] = e.name;
    item["joints"] = e.joints;
    Json params = Json::object();
    for (const auto& [key, value] : e.params) params[key] = value;
    item["params"] = params;
    effects.push_back(item);
  }
  doc["effect_list"] = effects;
  Json options;
  options["form"] = ToString(model.options().form);
  options["friction_width"] = model.options().friction_width;
  options["broad_prior_std"] = model.options().broad_prior_std;
  options["max_explicit_features"] = model.options().max_explicit_features;
  doc["options"] = options;
  if (const auto& chain = model.options().rigid_body) {
    // The robot itself: the URDF document, which chain of it, and the parameters the model's
    // prior is centred on.
    Json robot;
    robot["urdf"] = chain->urdf();
    robot["source"] = chain->source();
    robot["root"] = chain->root();
    robot["tip"] = chain->tip();
    robot["gravity"] = NumberArray(Vector(chain->gravity()));
    robot["parameters"] = EncodeMatrix(chain->parameters(), false);
    doc["rigid_body"] = robot;
  }
  doc["num_joints"] = model.num_joints();
  doc["uses_time"] = model.uses_time();
  doc["input_dim"] = model.input_dim();
  doc["num_features"] = model.feature_map() ? model.feature_map()->dim() : 0;
  doc["form"] = ToString(gp.form());

  doc["hyperparameters"] = hyper;
  if (scaled) doc["latent_variance_scale"] = NumberArray(model.latent_variance_scale());

  const double lml = gp.LogMarginalLikelihood();
  if (std::isfinite(lml)) doc["log_marginal_likelihood"] = lml;

  if (const RegressorGP* regressor = gp.regressor()) {
    const RegressorGPState s = regressor->State();
    Json g;
    g["prior_mean"] = EncodeMatrix(s.prior_mean, false);
    g["prior_variance"] = EncodeMatrix(s.prior_variance, false);
    g["noise_variance"] = EncodeMatrix(s.noise_variance, false);
    Json gram = Json::array();
    for (const Matrix& G : s.statistics.gram) gram.push_back(EncodeMatrix(G, false));
    g["gram"] = gram;
    g["cross"] = EncodeMatrix(s.statistics.cross, false);
    g["y_squared"] = EncodeMatrix(s.statistics.y_squared, false);
    g["count"] = s.statistics.count;
    doc["num_samples"] = static_cast<long long>(s.statistics.count);
    doc["regressor"] = g;
  } else if (const EulerLagrangeGP* euler = gp.euler_lagrange()) {
    // The data and the inducing states; the posterior is factorised again on load.
    RequireFiniteForSave("stored inputs", euler->inputs());
    RequireFiniteForSave("stored targets", euler->targets());
    Json e;
    e["inputs"] = EncodeMatrix(euler->inputs(), false);
    e["targets"] = EncodeMatrix(euler->targets(), false);
    if (euler->dtc()) e["inducing"] = EncodeMatrix(euler->states(), false);
    doc["num_samples"] = static_cast<long long>(euler->inputs().rows());
    doc["euler_lagrange"] = e;
  } else if (const WeightSpaceGP* ws = gp.weight_space()) {
    const WeightSpaceGPState s = ws->State();
    doc["num_samples"] = s.num_samples;
    doc["weight_space"] = WeightSpaceJson(s);
  } else if (gp.per_output()) {
    // One posterior per joint in weight space; in function space the points, stored once.
    const RobotModelState state = model.State();
    if (gp.form() == Form::kWeightSpace) {
      Json joints = Json::array();
      for (const WeightSpaceGPState& s : state.joint_weight_space) {
        joints.push_back(WeightSpaceJson(s));
      }
      doc["num_samples"] = state.joint_weight_space.front().num_samples;
      doc["joint_weight_space"] = joints;
    } else {
      doc["num_samples"] = state.inputs.rows();
      doc["function_space"] = FunctionSpaceJson(state.inputs, state.targets);
    }
  } else {
    const KernelGP& fs = *gp.function_space();
    doc["num_samples"] = fs.size();
    doc["function_space"] = FunctionSpaceJson(fs.inputs(), fs.targets());
  }
  doc["checksum"] = Checksum(doc);
  return doc;
}

// ---- the posterior file ---------------------------------------------------------------------

constexpr char kPosteriorMagic[] = "structgp posterior file\n";
constexpr uint32_t kPosteriorVersion = 1;
// Longest model-file checksum text a posterior file may carry ("crc32:xxxxxxxx" today).
constexpr uint32_t kMaxPosteriorChecksumLength = 256;

bool LittleEndian() {
  const uint16_t one = 1;
  unsigned char first = 0;
  std::memcpy(&first, &one, 1);
  return first == 1;
}

template <class T>
void AppendValue(std::string* out, T value) {
  char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  out->append(bytes, sizeof(T));
}

void AppendDoubles(std::string* out, const double* values, size_t count) {
  out->append(reinterpret_cast<const char*>(values), count * sizeof(double));
}

// Reads a posterior file for a model file with checksum `model_checksum` and p N = pn inducing
// torques. Null when there is none, or (with *note saying why) when it cannot be used.
std::shared_ptr<EulerLagrangeGP::DtcFactors> ReadPosteriorFile(
    const std::string& file, const std::string& model_checksum, Eigen::Index pn,
    std::string* note) {
  std::error_code ec;
  if (!std::filesystem::exists(file, ec)) return nullptr;
  if (!LittleEndian()) {
    *note = "not read on a machine that is not little-endian";
    return nullptr;
  }
  std::ifstream in(file, std::ios::binary);
  if (!in) {
    *note = std::string("cannot be opened: ") + std::strerror(errno);
    return nullptr;
  }
  uLong crc = crc32(0L, Z_NULL, 0);
  auto read = [&](void* destination, size_t size) {
    in.read(static_cast<char*>(destination), static_cast<std::streamsize>(size));
    if (static_cast<size_t>(in.gcount()) != size) return false;
    crc = Crc32Update(crc, static_cast<const char*>(destination), size);
    return true;
  };
  const std::string truncated = "damaged: it ends early (truncated)";
  char magic[sizeof(kPosteriorMagic) - 1];
  if (!read(magic, sizeof(magic)) ||
      std::memcmp(magic, kPosteriorMagic, sizeof(magic)) != 0) {
    *note = "not a structgp posterior file (it does not start with \"structgp posterior file\")";
    return nullptr;
  }
  uint32_t version = 0, checksum_length = 0;
  if (!read(&version, sizeof(version))) {
    *note = truncated;
    return nullptr;
  }
  if (version != kPosteriorVersion) {
    *note = "version " + std::to_string(version) + ", this build reads version " +
            std::to_string(kPosteriorVersion);
    return nullptr;
  }
  if (!read(&checksum_length, sizeof(checksum_length)) ||
      checksum_length > kMaxPosteriorChecksumLength) {
    *note = checksum_length > kMaxPosteriorChecksumLength ? "damaged: a bad header" : truncated;
    return nullptr;
  }
  std::string checksum(checksum_length, '\0');
  if (!read(checksum.data(), checksum.size())) {
    *note = truncated;
    return nullptr;
  }
  if (checksum != model_checksum) {
    *note = "written for another model file (its checksum " + checksum + ", the model file's " +
            model_checksum + ")";
    return nullptr;
  }
  uint64_t stored_pn = 0;
  if (!read(&stored_pn, sizeof(stored_pn))) {
    *note = truncated;
    return nullptr;
  }
  if (stored_pn != static_cast<uint64_t>(pn)) {
    *note = "damaged: it holds " + std::to_string(stored_pn) + " inducing torques, the model " +
            std::to_string(pn);
    return nullptr;
  }
  auto factors = std::make_shared<EulerLagrangeGP::DtcFactors>();
  factors->alpha.resize(pn);
  factors->factor_b = Matrix::Zero(pn, pn);
  bool complete = read(&factors->log_evidence, sizeof(double)) &&
                  read(factors->alpha.data(), static_cast<size_t>(pn) * sizeof(double));
  for (Eigen::Index c = 0; complete && c < pn; ++c) {
    complete = read(factors->factor_b.col(c).data() + c,
                    static_cast<size_t>(pn - c) * sizeof(double));
  }
  const uLong computed = crc;
  uint32_t stored_crc = 0;
  if (!complete || !read(&stored_crc, sizeof(stored_crc))) {
    *note = truncated;
    return nullptr;
  }
  if (in.peek() != std::char_traits<char>::eof()) {
    *note = "damaged: bytes after its end";
    return nullptr;
  }
  if (stored_crc != static_cast<uint32_t>(computed)) {
    *note = "damaged: its CRC-32 does not match its contents";
    return nullptr;
  }
  if (EulerLagrangeGP::CheckDtcFactors(pn, *factors) != Status::kOk) {
    *note = "damaged: its factors are not those of a posterior (a non-finite entry, or a "
            "diagonal entry of B's factor below 1)";
    return nullptr;
  }
  return factors;
}

}  // namespace

std::string ModelFileText(const RobotModel& model) { return ModelFileJson(model).dump(2) + "\n"; }

std::string PosteriorFilePath(const std::string& model_path) { return model_path + ".posterior"; }

std::string PosteriorFileBytes(const RobotModel& model) {
  if (!model.fitted()) throw std::invalid_argument("SaveModel: the model is not fitted");
  const EulerLagrangeGP* euler = model.gp().euler_lagrange();
  if (euler == nullptr || !euler->dtc() || !LittleEndian()) return std::string();
  const std::string checksum = ModelFileJson(model).at("checksum").get<std::string>();
  const Vector& alpha = euler->dtc_alpha();
  const Matrix& factor_b = euler->dtc_factor_b();
  const Eigen::Index pn = alpha.size();
  RequireFiniteForSave("the posterior's alpha", alpha);
  std::string out;
  out.reserve(sizeof(kPosteriorMagic) + checksum.size() + 64 +
              static_cast<size_t>(pn) * static_cast<size_t>(pn + 3) / 2 * sizeof(double));
  out.append(kPosteriorMagic, sizeof(kPosteriorMagic) - 1);
  AppendValue(&out, kPosteriorVersion);
  AppendValue(&out, static_cast<uint32_t>(checksum.size()));
  out.append(checksum);
  AppendValue(&out, static_cast<uint64_t>(pn));
  AppendValue(&out, euler->LogMarginalLikelihood());
  AppendDoubles(&out, alpha.data(), static_cast<size_t>(pn));
  for (Eigen::Index c = 0; c < pn; ++c) {
    const auto column = factor_b.col(c).tail(pn - c);
    RequireFiniteForSave("the posterior's factor", column);
    AppendDoubles(&out, factor_b.col(c).data() + c, static_cast<size_t>(pn - c));
  }
  const uLong crc = Crc32Update(crc32(0L, Z_NULL, 0), out.data(), out.size());
  AppendValue(&out, static_cast<uint32_t>(crc));
  return out;
}

void SaveModel(const std::string& path, const RobotModel& model, const SaveOptions& options) {
  const std::string text = ModelFileText(model);
  const std::string posterior = options.posterior_file ? PosteriorFileBytes(model) : std::string();
  const std::string posterior_path = PosteriorFilePath(path);
  // The posterior file first: a crash between the two leaves it next to the old model file,
  // whose checksum it does not carry, so that LoadModel does not use it.
  if (!posterior.empty()) WriteTextAtomically(posterior_path, posterior);
  WriteTextAtomically(path, text);
  if (posterior.empty()) {
    std::error_code ec;
    std::filesystem::remove(posterior_path, ec);  // the replaced file's, if any
  }
}

// ---- loading --------------------------------------------------------------------------------

namespace {

void CheckLoadOptions(const LoadOptions& options) {
  if (options.num_threads < 1) {
    throw std::invalid_argument("LoadOptions::num_threads: expected >= 1, got " +
                                std::to_string(options.num_threads));
  }
}

// The parts of a model file that say what it holds (ParseModelFile, ReadModelFileHeader), each
// checked as it is read.

// Its format, version and checksum.
void CheckEnvelope(const Json& doc, const FieldReader& r) {
  if (!doc.is_object()) {
    r.Fail("not a structgp model file (expected a JSON object with \"format\": \"" +
           std::string(kModelFileFormat) + "\")");
  }
  const auto format = doc.find("format");
  if (format == doc.end()) {
    r.Fail("not a structgp model file (no \"format\" field; expected \"format\": \"" +
           std::string(kModelFileFormat) + "\")");
  }
  if (!format->is_string() || format->get<std::string>() != kModelFileFormat) {
    r.Fail("not a structgp model file (\"format\" is " + format->dump() + ", expected \"" +
           kModelFileFormat + "\")");
  }
  const auto version = doc.find("version");
  if (version == doc.end() || !version->is_number_integer()) {
    r.Fail("model file without an integer \"version\" field");
  }
  const long long v = version->get<long long>();
  if (v < kOldestModelFileVersion || v > kModelFileVersion) {
    r.Fail("unsupported model file version " + std::to_string(v) + ": this build reads versions " +
           std::to_string(kOldestModelFileVersion) + " to " + std::to_string(kModelFileVersion) +
           (v > kModelFileVersion ? " (the file was written by a newer structgp)" : ""));
  }
  const auto checksum = doc.find("checksum");
  if (checksum == doc.end() || !checksum->is_string()) {
    r.Fail("model file without a \"checksum\" field");
  }
  const std::string computed = Checksum(doc);
  if (checksum->get<std::string>() != computed) {
    r.Fail("checksum mismatch: the file says " + checksum->get<std::string>() +
           ", its contents give " + computed + "; the file is corrupted or was edited");
  }
}

// The model and its effects ("model", "effect_list").
ModelSpec ReadSpec(const Json& doc, const FieldReader& r) {
  ModelSpec spec;
  try {
    spec = ParseModelSpec(r.String(doc, "", "model"));
  } catch (const std::invalid_argument& e) {
    r.FailField("model", e.what());
  }
  // The version that changed the Euler-Lagrange space (M_jk of degree 1 in the angles between
  // j and k): an older file's posterior (lag) or hyper-parameters (lagk) belong to the old one.
  constexpr long long kChainDegreesVersion = 2;
  if ((spec.base == BaseModel::kLag || spec.base == BaseModel::kLagk) &&
      doc.at("version").get<long long>() < kChainDegreesVersion) {
    r.FailField("model", std::string("a '") + ToString(spec.base) +
                             "' model of a version 1 file: its Euler-Lagrange space changed in "
                             "version 2 (M_jk is of degree 1 in the angles between j and k); fit "
                             "it again from its data (structgp fit)");
  }
  const Json& effects = r.Get(doc, "", "effect_list");
  if (!effects.is_array()) r.FailField("effect_list", "expected an array");
  for (size_t i = 0; i < effects.size(); ++i) {
    const std::string prefix = "effect_list[" + std::to_string(i) + "]";
    EffectSpec e;
    e.name = r.String(effects[i], prefix, "name");
    const Json& joints = r.Get(effects[i], prefix, "joints");
    if (!joints.is_array()) r.FailField(prefix + ".joints", "expected an array of joints");
    for (const Json& j : joints) {
      if (!j.is_number_integer()) r.FailField(prefix + ".joints", "expected integers");
      e.joints.push_back(j.get<int>());
    }
    const Json& params = r.Get(effects[i], prefix, "params");
    if (!params.is_object()) r.FailField(prefix + ".params", "expected an object");
    for (const auto& [key, value] : params.items())
      e.params[key] = r.Number(params, prefix + ".params", key.c_str());
    spec.effects.push_back(std::move(e));
  }
  return spec;
}

// The form the model was fitted in ("form").
Form ReadForm(const Json& doc, const FieldReader& r) {
  bool ok = false;
  const Form form = ParseForm(r.String(doc, "", "form"), &ok);
  if (!ok || form == Form::kAuto) {
    r.FailField("form",
                "expected 'weight_space', 'function_space', 'regressor' or 'euler_lagrange'");
  }
  return form;
}

int ReadNumJoints(const Json& doc, const FieldReader& r) {
  return static_cast<int>(r.Integer(doc, "", "num_joints", 1, 1000));
}

// "hyperparameters"; *kernel_parameters: its "kernel_parameters".
Hyperparameters ReadOneSet(const Json& hj, const std::string& prefix, const FieldReader& r,
                           Vector* kernel_parameters) {
  Hyperparameters hyper;
  hyper.shape = r.Numbers(hj, prefix, "shape");
  hyper.log_block_scale = r.Numbers(hj, prefix, "log_block_scale");
  hyper.log_noise_std = r.Number(hj, prefix, "log_noise_std");
  hyper.log_output_scale = r.Numbers(hj, prefix, "log_output_scale");
  *kernel_parameters = r.Numbers(hj, prefix, "kernel_parameters");
  return hyper;
}

// "hyperparameters"; *kernel_parameters: its "kernel_parameters". Each joint's own set
// ("per_joint", version 3) has its kernel's parameters in shape (the library checks them).
Hyperparameters ReadHyperparameters(const Json& doc, const FieldReader& r,
                                    Vector* kernel_parameters) {
  const Json& hj = r.Get(doc, "", "hyperparameters");
  Hyperparameters hyper = ReadOneSet(hj, "hyperparameters", r, kernel_parameters);
  if (hj.is_object() && hj.contains("per_joint")) {
    const Json& joints = hj.at("per_joint");
    if (!joints.is_array() || joints.empty()) {
      r.FailField("hyperparameters.per_joint", "expected a non-empty array of objects");
    }
    for (size_t j = 0; j < joints.size(); ++j) {
      Vector own_kernel;
      Hyperparameters own = ReadOneSet(
          joints[j], "hyperparameters.per_joint[" + std::to_string(j) + "]", r, &own_kernel);
      if (own_kernel.size() > 0) own.shape = own_kernel;
      hyper.per_output.push_back(std::move(own));
    }
  }
  return hyper;
}

WeightSpaceGPState ReadWeightSpace(const Json& w, const std::string& p, const FieldReader& r) {
  WeightSpaceGPState ws;
  ws.prior_variance = r.DecodedVector(w, p, "prior_variance");
  ws.noise_variance = r.Number(w, p, "noise_variance");
  ws.output_scales = r.DecodedVector(w, p, "output_scales");
  ws.covariance_factor = r.DecodedMatrix(w, p, "covariance_factor");
  ws.weights = r.DecodedMatrix(w, p, "weights");
  ws.y_squared = r.DecodedVector(w, p, "y_squared");
  ws.weight_sum = r.Number(w, p, "weight_sum");
  ws.log_weight_sum = r.Number(w, p, "log_weight_sum");
  ws.log_prior_broadening = r.Number(w, p, "log_prior_broadening");
  ws.sample_count = r.Number(w, p, "sample_count");
  ws.num_samples = static_cast<long>(r.Integer(w, p, "num_samples", -(1LL << 62), 1LL << 62));
  return ws;
}

}  // namespace

namespace {

// ParseModelFile; with posterior_path (LoadModel), a lagk model through inducing states takes
// its posterior's factors from that file when it can be used (summary says which).
RobotModel ParseModelFileWith(const std::string& text, const std::string& path,
                              const LoadOptions& load, const std::string* posterior_path,
                              LoadSummary* summary) {
  CheckLoadOptions(load);
  const FieldReader r(path);
  const Json doc = ParseJson(text, path);
  CheckEnvelope(doc, r);
  // The contents are as written by SaveModel (or by a careful hand); check them all the same.
  const ModelSpec spec = ReadSpec(doc, r);

  RobotModelOptions options;
  const Json& o = r.Get(doc, "", "options");
  bool form_ok = false;
  options.form = ParseForm(r.String(o, "options", "form"), &form_ok);
  if (!form_ok) r.FailField("options.form", "expected 'auto', 'weight_space' or 'function_space'");
  options.friction_width = r.Number(o, "options", "friction_width");
  options.broad_prior_std = r.Number(o, "options", "broad_prior_std");
  // Files written before this option existed used the explicit pol map at every size.
  options.max_explicit_features =
      o.contains("max_explicit_features")
          ? static_cast<int>(r.Integer(o, "options", "max_explicit_features", 1, 1 << 30))
          : (1 << 30);
  if (spec.base == BaseModel::kRbd || spec.rigid_body_features) {
    const Json& robot = r.Get(doc, "", "rigid_body");
    UrdfOptions urdf;
    urdf.root = r.String(robot, "rigid_body", "root");
    urdf.tip = r.String(robot, "rigid_body", "tip");
    const Vector gravity = r.Numbers(robot, "rigid_body", "gravity");
    if (gravity.size() != 3) r.FailField("rigid_body.gravity", "expected 3 numbers");
    urdf.gravity = gravity;
    try {
      const RigidBodyChain chain = RigidBodyChain::FromUrdfString(
          r.String(robot, "rigid_body", "urdf"), urdf, r.String(robot, "rigid_body", "source"));
      options.rigid_body = std::make_shared<const RigidBodyChain>(
          chain.WithParameters(r.DecodedVector(robot, "rigid_body", "parameters")));
    } catch (const std::invalid_argument& e) {
      r.FailField("rigid_body", e.what());
    }
  }
  const int num_joints = ReadNumJoints(doc, r);
  const bool uses_time = r.Boolean(doc, "", "uses_time");
  const int input_dim = static_cast<int>(r.Integer(doc, "", "input_dim", 1, 1 << 20));
  const long long num_features = r.Integer(doc, "", "num_features", 0, 1LL << 40);
  const Form active = ReadForm(doc, r);

  Vector kernel_parameters;
  const Hyperparameters hyper = ReadHyperparameters(doc, r, &kernel_parameters);

  // Everything below builds library objects, whose checks throw std::invalid_argument.
  try {
    RobotModel probe(spec, num_joints, options);
    if (probe.uses_time() != uses_time || probe.input_dim() != input_dim) {
      r.Fail("inconsistent model file: model '" + Label(spec) + "' has " +
             std::to_string(probe.input_dim()) + " inputs, the file says " +
             std::to_string(input_dim));
    }
    const long long map_dim = probe.feature_map() ? probe.feature_map()->dim() : 0;
    if (map_dim != num_features) {
      r.Fail("inconsistent model file: model '" + Label(spec) + "' has " + std::to_string(map_dim) +
             " features, the file says " + std::to_string(num_features));
    }

    RobotModelState state;
    state.spec = spec;
    state.num_joints = num_joints;
    state.options = options;
    state.options.batch.num_threads = load.num_threads;
    state.hyperparameters = hyper;
    state.form = active;
    if (doc.contains("latent_variance_scale")) {
      state.latent_variance_scale = r.Numbers(doc, "", "latent_variance_scale");
      if (state.latent_variance_scale.size() != num_joints) {
        r.FailField("latent_variance_scale",
                    "expected " + std::to_string(num_joints) + " numbers (one per joint), got " +
                        std::to_string(state.latent_variance_scale.size()));
      }
      for (Eigen::Index j = 0; j < state.latent_variance_scale.size(); ++j) {
        const double kappa = state.latent_variance_scale[j];
        if (!(std::isfinite(kappa) && kappa > 0.0)) {
          r.FailField("latent_variance_scale[" + std::to_string(j) + "]",
                      "expected a finite number > 0, got " + std::to_string(kappa));
        }
      }
    }
    if (probe.kernel() != nullptr) {
      // A kernel's parameters: "kernel_parameters" in the file, Hyperparameters::shape in the
      // model.
      if (kernel_parameters.size() != probe.kernel()->num_parameters()) {
        r.FailField("hyperparameters.kernel_parameters",
                    "expected " + std::to_string(probe.kernel()->num_parameters()) +
                        " values, got " + std::to_string(kernel_parameters.size()));
      }
      state.hyperparameters.shape = kernel_parameters;
    }

    if (active == Form::kEulerLagrange) {
      const std::string p = "euler_lagrange";
      const Json& e = r.Get(doc, "", "euler_lagrange");
      state.inputs = r.DecodedMatrix(e, p, "inputs");
      state.targets = r.DecodedMatrix(e, p, "targets");
      if (e.contains("inducing")) state.inducing = r.DecodedMatrix(e, p, "inducing");
      // The posterior is factorised again (O((m N)^3) exact, O(m N (p N)^2) through p states),
      // unless its posterior file holds the factors of the pass over the rows.
      if (posterior_path != nullptr && state.inducing.size() > 0) {
        state.euler_lagrange_factors = ReadPosteriorFile(
            *posterior_path, doc.at("checksum").get<std::string>(),
            state.inducing.rows() * num_joints, &summary->posterior_file_note);
        summary->posterior_file_read = state.euler_lagrange_factors != nullptr;
      }
      return RobotModel::FromState(state);
    }
    if (active == Form::kRegressor) {
      const std::string p = "regressor";
      const Json& g = r.Get(doc, "", "regressor");
      RegressorGPState& rs = state.regressor;
      rs.prior_mean = r.DecodedVector(g, p, "prior_mean");
      rs.prior_variance = r.DecodedVector(g, p, "prior_variance");
      rs.noise_variance = r.DecodedVector(g, p, "noise_variance");
      const Json& gram = r.Get(g, p, "gram");
      if (!gram.is_array()) r.FailField("regressor.gram", "expected an array of matrices");
      for (size_t j = 0; j < gram.size(); ++j) {
        Json holder;
        holder["g"] = gram[j];
        rs.statistics.gram.push_back(
            r.DecodedMatrix(holder, "regressor.gram[" + std::to_string(j) + "]", "g"));
      }
      rs.statistics.cross = r.DecodedMatrix(g, p, "cross");
      rs.statistics.y_squared = r.DecodedVector(g, p, "y_squared");
      rs.statistics.count = r.Number(g, p, "count");
      return RobotModel::FromState(state);
    }
    if (active == Form::kWeightSpace) {
      if (!probe.feature_map()) r.Fail("inconsistent model file: a kernel model in weight space");
      if (hyper.is_per_output()) {
        const Json& joints = r.Get(doc, "", "joint_weight_space");
        if (!joints.is_array() || static_cast<int>(joints.size()) != num_joints) {
          r.FailField("joint_weight_space",
                      "expected an array of " + std::to_string(num_joints) +
                          " weight-space states (one per joint)");
        }
        for (size_t j = 0; j < joints.size(); ++j) {
          const std::string p = "joint_weight_space[" + std::to_string(j) + "]";
          WeightSpaceGPState ws = ReadWeightSpace(joints[j], p, r);
          if (ws.prior_variance.size() != num_features || ws.output_scales.size() != 1) {
            r.Fail("inconsistent model file: " + p + " has " +
                   std::to_string(ws.prior_variance.size()) + " features and " +
                   std::to_string(ws.output_scales.size()) + " outputs, expected " +
                   std::to_string(num_features) + " and 1");
          }
          state.joint_weight_space.push_back(std::move(ws));
        }
        return RobotModel::FromState(state);
      }
      const WeightSpaceGPState& ws = state.weight_space =
          ReadWeightSpace(r.Get(doc, "", "weight_space"), "weight_space", r);
      if (ws.prior_variance.size() != num_features || ws.output_scales.size() != num_joints) {
        r.Fail("inconsistent model file: the weight-space state has " +
               std::to_string(ws.prior_variance.size()) + " features and " +
               std::to_string(ws.output_scales.size()) + " outputs, the model " +
               std::to_string(num_features) + " and " + std::to_string(num_joints));
      }
      // The posterior is restored as it is: no fit.
      return RobotModel::FromState(state);
    }

    const std::string p = "function_space";
    const Json& f = r.Get(doc, "", "function_space");
    state.inputs = r.DecodedMatrix(f, p, "inputs");
    state.targets = r.DecodedMatrix(f, p, "targets");
    const Matrix& X = state.inputs;
    const Matrix& Y = state.targets;
    if (X.cols() != input_dim || Y.cols() != num_joints || X.rows() != Y.rows()) {
      r.Fail("inconsistent model file: stored inputs are " + std::to_string(X.rows()) + " x " +
             std::to_string(X.cols()) + " and targets " + std::to_string(Y.rows()) + " x " +
             std::to_string(Y.cols()) + ", the model needs " + std::to_string(input_dim) +
             " input and " + std::to_string(num_joints) + " target columns");
    }
    // The stored points are factorised again (O(m^3)), all of them, in function space.
    return RobotModel::FromState(state);
  } catch (const std::invalid_argument& e) {
    r.Fail(std::string("inconsistent model file: ") + e.what());
  }
}

std::string ReadModelFileText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    throw DataError(path, 0, 0, std::string("cannot open for reading: ") + std::strerror(errno));
  }
  std::ostringstream buffer;
  buffer << in.rdbuf();
  if (in.bad()) {
    throw DataError(path, 0, 0, std::string("cannot read: ") + std::strerror(errno));
  }
  return buffer.str();
}

}  // namespace

RobotModel ParseModelFile(const std::string& text, const std::string& path,
                          const LoadOptions& load) {
  LoadSummary summary;
  return ParseModelFileWith(text, path, load, nullptr, &summary);
}

RobotModel LoadModel(const std::string& path, const LoadOptions& options, LoadSummary* summary) {
  CheckLoadOptions(options);  // before reading the file
  LoadSummary local;
  LoadSummary* out = summary != nullptr ? summary : &local;
  *out = LoadSummary();
  const std::string posterior_path = PosteriorFilePath(path);
  return ParseModelFileWith(ReadModelFileText(path), path, options,
                            options.posterior_file ? &posterior_path : nullptr, out);
}

ModelFileHeader ParseModelFileHeader(const std::string& text, const std::string& path) {
  const FieldReader r(path);
  const Json doc = ParseJson(text, path);
  CheckEnvelope(doc, r);
  ModelFileHeader header;
  header.spec = ReadSpec(doc, r);
  header.num_joints = ReadNumJoints(doc, r);
  header.form = ReadForm(doc, r);
  Vector kernel_parameters;
  header.hyperparameters = ReadHyperparameters(doc, r, &kernel_parameters);
  if (kernel_parameters.size() > 0) header.hyperparameters.shape = kernel_parameters;
  return header;
}

ModelFileHeader ReadModelFileHeader(const std::string& path) {
  return ParseModelFileHeader(ReadModelFileText(path), path);
}

}  // namespace structgp
