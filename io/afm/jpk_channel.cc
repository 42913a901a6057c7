#include "io/afm/jpk_channel.h"

#include <cstdint>
#include <cstring>

#include "io/afm/text_util.h"

namespace cellflow::afm {
namespace {

enum class Raw { kI16, kU16, kI32, kU32, kI64, kF32, kF64 };

std::size_t raw_size(Raw r) {
  switch (r) {
    case Raw::kI16:
    case Raw::kU16:
      return 2;
    case Raw::kI32:
    case Raw::kU32:
    case Raw::kF32:
      return 4;
    case Raw::kI64:
    case Raw::kF64:
      return 8;
  }
  return 0;
}

std::uint64_t load_be(const unsigned char* p, std::size_t n) {
  std::uint64_t v = 0;
  for (std::size_t i = 0; i < n; ++i) v = (v << 8) | p[i];
  return v;
}

double decode_one(const unsigned char* p, Raw r) {
  const std::uint64_t v = load_be(p, raw_size(r));
  switch (r) {
    case Raw::kI16:
      return static_cast<std::int16_t>(static_cast<std::uint16_t>(v));
    case Raw::kU16:
      return static_cast<std::uint16_t>(v);
    case Raw::kI32:
      return static_cast<std::int32_t>(static_cast<std::uint32_t>(v));
    case Raw::kU32:
      return static_cast<std::uint32_t>(v);
    case Raw::kI64:
      return static_cast<double>(static_cast<std::int64_t>(v));
    case Raw::kF32: {
      const auto bits = static_cast<std::uint32_t>(v);
      float f;
      std::memcpy(&f, &bits, sizeof f);
      return f;
    }
    case Raw::kF64: {
      double d;
      std::memcpy(&d, &v, sizeof d);
      return d;
    }
  }
  return 0.0;
}

// "short", "short-data", "memory-short-data" -> "short".
std::string normalise_type(std::string t) {
  if (t.rfind("memory-", 0) == 0) t.erase(0, 7);
  if (t.size() > 5 && t.compare(t.size() - 5, 5, "-data") == 0) t.erase(t.size() - 5);
  return t;
}

StatusOr<Raw> integer_encoding(const std::string& encoder, const std::string& where) {
  if (encoder == "signedshort") return Raw::kI16;
  if (encoder == "unsignedshort") return Raw::kU16;
  if (encoder == "signedinteger") return Raw::kI32;
  if (encoder == "unsignedinteger") return Raw::kU32;
  if (encoder == "signedlong") return Raw::kI64;
  return invalid_argument(where + ": unsupported encoder type '" + encoder + "'");
}

StatusOr<double> number_key(const Properties& props, const std::string& channel, const std::string& suffix,
                            const std::string& where) {
  const std::string* v = jpk_channel_key(props, channel, suffix);
  if (v == nullptr)
    return invalid_argument(where + ": header lacks channel." + channel + ".[data.]" + suffix);
  const auto d = parse_number(*v);
  if (!d)
    return invalid_argument(where + ": channel." + channel + "." + suffix + " = '" + *v +
                            "' is not a number");
  return *d;
}

}  // namespace

const std::string* jpk_channel_key(const Properties& props, const std::string& channel,
                                   const std::string& suffix) {
  for (const std::string& key :
       {"channel." + channel + ".data." + suffix, "channel." + channel + "." + suffix}) {
    const auto it = props.find(key);
    if (it != props.end()) return &it->second;
  }
  return nullptr;
}

std::optional<double> jpk_conversion_multiplier(const Properties& props, const std::string& channel,
                                                const std::string& slot) {
  const std::string* v =
      jpk_channel_key(props, channel, "conversion-set.conversion." + slot + ".scaling.multiplier");
  if (v == nullptr) return std::nullopt;
  return parse_number(*v);
}

StatusOr<std::vector<double>> decode_jpk_channel(const Properties& props, std::string_view data,
                                                 const JpkDecodeRequest& req) {
  const std::string& where = req.where;
  const std::string& ch = req.channel;

  // Storage type, then the integer encoding where the type needs one.
  const std::string* type_key = jpk_channel_key(props, ch, "type");
  const std::string* encoder_key = jpk_channel_key(props, ch, "encoder.type");
  std::string type = type_key ? normalise_type(*type_key) : "";
  if (type.empty() && encoder_key != nullptr) type = "integer";  // only the encoder says
  Raw raw;
  bool needs_scaling = true;
  if (type == "short" || type == "integer" || type == "long") {
    if (encoder_key == nullptr)
      return invalid_argument(where + ": " + type + " data without an encoder type");
    auto enc = integer_encoding(*encoder_key, where);
    if (!enc.ok()) return enc.status();
    raw = *enc;
    if (raw_size(raw) != (type == "short" ? 2u : type == "integer" ? 4u : 8u)) {
      return invalid_argument(where + ": encoder '" + *encoder_key + "' does not match data type '" + type +
                              "'");
    }
  } else if (type == "float") {
    raw = Raw::kF32;
    needs_scaling = encoder_key != nullptr;
  } else if (type == "double") {
    raw = Raw::kF64;
    needs_scaling = encoder_key != nullptr;
  } else {
    return invalid_argument(where + ": unsupported data type '" + (type_key ? *type_key : std::string()) +
                            "'");
  }

  const std::size_t width = raw_size(raw);
  if (req.num_points > data.size() / width || data.size() != req.num_points * width) {
    return invalid_argument(where + ": " + std::to_string(data.size()) + " bytes of data, but " +
                            std::to_string(req.num_points) + " points of " + std::to_string(width) +
                            " bytes are declared");
  }

  double enc_offset = 0.0, enc_multiplier = 1.0;
  if (needs_scaling) {
    auto off = number_key(props, ch, "encoder.scaling.offset", where);
    if (!off.ok()) return off.status();
    auto mul = number_key(props, ch, "encoder.scaling.multiplier", where);
    if (!mul.ok()) return mul.status();
    enc_offset = *off;
    enc_multiplier = *mul;
  }

  // Conversion chain from the requested slot back to the base slot.
  const std::string conv = "conversion-set.";
  const std::string* base = jpk_channel_key(props, ch, conv + "conversions.base");
  const std::string* list = jpk_channel_key(props, ch, conv + "conversions.list");
  const std::string* dflt = jpk_channel_key(props, ch, conv + "conversions.default");
  std::vector<std::pair<double, double>> steps;  // (multiplier, offset), target first
  if (base != nullptr) {
    std::string slot = req.slot;
    bool listed = slot == *base;
    if (list != nullptr) {
      for (std::string_view s : split_fields(*list, ' ')) listed = listed || s == slot;
    }
    if (!listed) slot = dflt ? *dflt : *base;
    for (int guard = 0; slot != *base; ++guard) {
      if (guard > 16)
        return invalid_argument(where + ": conversion chain of " + ch + " does not reach its base");
      const std::string p = conv + "conversion." + slot + ".";
      const std::string* style = jpk_channel_key(props, ch, p + "scaling.type");
      if (style != nullptr && *style != "linear") {
        return invalid_argument(where + ": conversion '" + slot + "' of " + ch + " has scaling type '" +
                                *style + "', only linear is supported");
      }
      auto off = number_key(props, ch, p + "scaling.offset", where);
      if (!off.ok()) return off.status();
      auto mul = number_key(props, ch, p + "scaling.multiplier", where);
      if (!mul.ok()) return mul.status();
      const auto over = req.multiplier_overrides.find(slot);
      steps.emplace_back(over != req.multiplier_overrides.end() ? over->second : *mul, *off);
      const std::string* next = jpk_channel_key(props, ch, p + "base-calibration-slot");
      if (next == nullptr)
        return invalid_argument(where + ": conversion '" + slot + "' of " + ch + " has no base slot");
      slot = *next;
    }
  }

  std::vector<double> out(req.num_points);
  const auto* bytes = reinterpret_cast<const unsigned char*>(data.data());
  for (std::size_t i = 0; i < req.num_points; ++i) {
    double v = decode_one(bytes + i * width, raw) * enc_multiplier + enc_offset;
    for (auto it = steps.rbegin(); it != steps.rend(); ++it) v = v * it->first + it->second;
    out[i] = v;
  }
  return out;
}

}  // namespace cellflow::afm
