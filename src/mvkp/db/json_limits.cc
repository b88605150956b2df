#include "mvkp/db/json_limits.h"

#include "mvkp/core/error.h"

namespace mvkp {
namespace {

using Json = nlohmann::json;

struct TooDeep {};
struct TooLong {};

}  // namespace

Json ParseJsonLimited(std::string_view text, const JsonLimits& limits, const std::string& what) {
  if (text.size() > limits.max_bytes)
    throw Error(ErrorCode::kInvalidArgument, what + ": " + std::to_string(text.size()) + " bytes, at most " +
                                                 std::to_string(limits.max_bytes));
  // The callback sees every event with the depth of its container; an array
  // or object opening at depth d is nesting level d + 1.
  const Json::parser_callback_t cb = [&](int depth, Json::parse_event_t event, Json& parsed) {
    if ((event == Json::parse_event_t::object_start || event == Json::parse_event_t::array_start) &&
        depth + 1 > limits.max_depth)
      throw TooDeep{};
    if ((event == Json::parse_event_t::key || event == Json::parse_event_t::value) && parsed.is_string() &&
        parsed.get_ref<const std::string&>().size() > limits.max_string_bytes)
      throw TooLong{};
    return true;
  };
  try {
    return Json::parse(text.begin(), text.end(), cb);
  } catch (const TooDeep&) {
    throw Error(ErrorCode::kInvalidArgument,
                what + ": nested deeper than " + std::to_string(limits.max_depth) + " levels");
  } catch (const TooLong&) {
    throw Error(ErrorCode::kInvalidArgument,
                what + ": a string longer than " + std::to_string(limits.max_string_bytes) + " bytes");
  } catch (const Json::exception& e) {
    // nlohmann's message names the position ("syntax error while parsing
    // value - invalid literal; last read: ..."): keep it, minus its prefix.
    std::string m = e.what();
    const auto p = m.find("] ");
    if (p != std::string::npos) m = m.substr(p + 2);
    throw Error(ErrorCode::kInvalidArgument, what + " is not valid JSON: " + m);
  }
}

bool TryParseJsonLimited(std::string_view text, Json& out, const JsonLimits& limits) {
  try {
    out = ParseJsonLimited(text, limits);
    return true;
  } catch (const Error&) {
    out = nullptr;
    return false;
  }
}

}  // namespace mvkp
