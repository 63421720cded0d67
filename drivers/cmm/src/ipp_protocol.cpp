// Tags, arguments, formatting and line framing of the I++ DME wire format; parsing is in
// ipp_parse.cpp.
#include "stampscan/drivers/cmm/ipp_protocol.hpp"

#include <array>
#include <charconv>
#include <cmath>
#include <cstdio>

namespace stampscan::drivers::cmm::ipp {

Tag Tag::command(int number) {
  if (number < 1 || number > 99999) throw std::invalid_argument("command tag out of 1..99999: " + std::to_string(number));
  return {Kind::Command, number};
}

Tag Tag::event(int number) {
  if (number < 0 || number > 9999) throw std::invalid_argument("event tag out of 0..9999: " + std::to_string(number));
  return {Kind::Event, number};
}

std::string Tag::str() const {
  std::array<char, 16> buffer{};
  if (kind == Kind::Event) {
    std::snprintf(buffer.data(), buffer.size(), "E%04d", number);
  } else {
    std::snprintf(buffer.data(), buffer.size(), "%05d", number);
  }
  return buffer.data();
}

Argument Argument::num(double value) {
  Argument a;
  a.kind = Kind::Number;
  a.number = value;
  return a;
}

Argument Argument::str(std::string value) {
  Argument a;
  a.kind = Kind::String;
  a.text = std::move(value);
  return a;
}

Argument Argument::name(std::string value) {
  Argument a;
  a.kind = Kind::Name;
  a.text = std::move(value);
  return a;
}

Argument Argument::call(std::string name, std::vector<Argument> args) {
  Argument a;
  a.kind = Kind::Call;
  a.text = std::move(name);
  a.args = std::move(args);
  return a;
}

bool Argument::operator==(const Argument& other) const {
  if (kind != other.kind) return false;
  if (kind == Kind::Number) return number == other.number;
  return text == other.text && args == other.args;
}

char toChar(ReplyKind kind) {
  switch (kind) {
    case ReplyKind::Ack: return '&';
    case ReplyKind::Complete: return '%';
    case ReplyKind::Data: return '#';
    case ReplyKind::Error: return '!';
  }
  return '?';
}

namespace {
std::string excerpt(std::string_view line) {
  constexpr std::size_t kShown = 120;  // a 64 KiB line must not become a 64 KiB message
  std::string text = sanitizeText(line.substr(0, kShown));
  if (line.size() > kShown) text += "...";
  return text;
}
}  // namespace

ProtocolError::ProtocolError(int error_number, std::size_t column, const std::string& reason, std::string_view line,
                             std::optional<Tag> tag)
    : std::runtime_error("column " + std::to_string(column) + ": " + reason +
                         (line.empty() ? std::string() : " in \"" + excerpt(line) + "\"")),
      error_number_(error_number),
      column_(column),
      reason_(reason),
      tag_(tag) {}

std::string formatNumber(double value) {
  if (!std::isfinite(value)) throw std::invalid_argument("I++ DME numbers must be finite");
  if (value == 0) return "0";  // also for -0, which has no use on the wire
  std::array<char, 64> buffer{};
  const auto digitsIn = [](std::string_view text) {
    std::size_t digits = 0;
    for (const char c : text.substr(0, text.find('e'))) digits += (c >= '0' && c <= '9') ? 1 : 0;
    return digits;
  };
  // The shortest text that reads back exactly, within the 16 digits of §6.1.4.2 (which count a
  // leading "0." too, hence the scientific form for 0.3333333333333333). A double that needs 17
  // significant digits is rounded to 16.
  auto result = std::to_chars(buffer.data(), buffer.data() + buffer.size(), value);
  std::string text(buffer.data(), result.ptr);
  if (digitsIn(text) <= kMaxNumberDigits) return text;
  result = std::to_chars(buffer.data(), buffer.data() + buffer.size(), value, std::chars_format::scientific);
  text.assign(buffer.data(), result.ptr);
  if (digitsIn(text) <= kMaxNumberDigits) return text;
  // Rounding the largest doubles to 16 digits would overflow; they get the largest 16-digit value.
  constexpr double kLargest16Digits = 1.797693134862315e308;
  if (std::abs(value) > kLargest16Digits) return value < 0 ? "-1.797693134862315e+308" : "1.797693134862315e+308";
  result = std::to_chars(buffer.data(), buffer.data() + buffer.size(), value, std::chars_format::scientific,
                         static_cast<int>(kMaxNumberDigits) - 1);
  return std::string(buffer.data(), result.ptr);
}

namespace {
void checkName(const std::string& name) {
  if (name.empty()) throw std::invalid_argument("I++ DME name is empty");
  bool start = true;
  for (const char c : name) {
    const bool alpha = (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z');
    const bool digit = c >= '0' && c <= '9';
    if (c == '.' && !start) {
      start = true;
    } else if (alpha || (digit && !start)) {
      start = false;
    } else {
      throw std::invalid_argument("not an I++ DME name: \"" + sanitizeText(name) + "\"");
    }
  }
  if (start) throw std::invalid_argument("I++ DME name ends with '.': \"" + sanitizeText(name) + "\"");
}

void checkString(const std::string& text) {
  for (const char c : text) {
    if (c == '"' || c < 32 || c > 126) throw std::invalid_argument("I++ DME strings cannot carry " + sanitizeText(text));
  }
}
}  // namespace

std::string formatArgument(const Argument& argument) {
  switch (argument.kind) {
    case Argument::Kind::Number: return formatNumber(argument.number);
    case Argument::Kind::String: checkString(argument.text); return '"' + argument.text + '"';
    case Argument::Kind::Name: checkName(argument.text); return argument.text;
    case Argument::Kind::Call: checkName(argument.text); return argument.text + '(' + formatArguments(argument.args) + ')';
  }
  return {};
}

std::string formatArguments(const std::vector<Argument>& arguments) {
  std::string text;
  for (std::size_t i = 0; i < arguments.size(); ++i) {
    if (i > 0) text += ", ";
    text += formatArgument(arguments[i]);
  }
  return text;
}

std::string formatCommand(const Command& command) {
  checkName(command.name);
  return command.tag.str() + ' ' + command.name + '(' + formatArguments(command.args) + ')';
}

std::string formatReply(const Reply& reply) {
  std::string line = reply.tag.str() + ' ' + toChar(reply.kind);
  switch (reply.kind) {
    case ReplyKind::Ack:
    case ReplyKind::Complete: break;
    case ReplyKind::Data:
      if (reply.data.empty()) throw std::invalid_argument("a data response needs data");
      line += ' ' + formatArguments(reply.data);
      break;
    case ReplyKind::Error: {
      const ErrorReport& e = reply.error;
      if (e.severity < 0 || e.severity > 9) throw std::invalid_argument("error class must be 0-9");
      if (e.number < 0 || e.number > 9999) throw std::invalid_argument("error number must be 0-9999");
      checkString(e.method);
      checkString(e.text);
      std::array<char, 8> number{};
      std::snprintf(number.data(), number.size(), "%04d", e.number);  // F2 :== UnsInt, 4 digits
      line += " Error(" + std::to_string(e.severity) + ", " + number.data() + ", \"" + e.method + "\", \"" +
              e.text + "\")";
      break;
    }
  }
  return line;
}

std::string sanitizeText(std::string_view text) {
  std::string out(text);
  for (char& c : out) {
    if (c == '"') {
      c = '\'';
    } else if (c < 32 || c > 126) {
      c = '?';
    }
  }
  return out;
}

std::optional<LineFramer::Line> LineFramer::next() {
  for (;;) {
    const std::size_t end = buffer_.find('\n', scanned_);
    if (discarding_) {
      if (end == std::string::npos) {
        buffer_.clear();
        scanned_ = 0;
        return std::nullopt;
      }
      buffer_.erase(0, end + 1);
      scanned_ = 0;
      discarding_ = false;
      continue;
    }
    if (end == std::string::npos) {
      scanned_ = buffer_.size();
      if (buffer_.size() <= max_ + 1) return std::nullopt;  // +1: the CR may already be here
      // Report an over-long line at once (its start, so the tag can be read) and drop the rest.
      Line line{buffer_.substr(0, max_), Problem::TooLong};
      buffer_.clear();
      scanned_ = 0;
      discarding_ = true;
      return line;
    }
    Line line{buffer_.substr(0, end), Problem::None};
    buffer_.erase(0, end + 1);
    scanned_ = 0;
    if (!line.text.empty() && line.text.back() == '\r') {
      line.text.pop_back();
    } else {
      line.problem = Problem::MissingCr;
    }
    if (line.text.size() > max_) {
      line.text.resize(max_);
      line.problem = Problem::TooLong;
    }
    return line;
  }
}

std::string frameLine(std::string_view line) {
  std::string framed(line);
  framed += "\r\n";
  return framed;
}

}  // namespace stampscan::drivers::cmm::ipp
