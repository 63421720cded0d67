// Parsing of I++ DME lines after the production rules of §6.1.4.2. Strict where the grammar is
// (spaces only around commas and parentheses, 5-character tags, numbers of at most 16 digits), so
// that the virtual CMM rejects what a real server would; lenient only in replies, where trailing
// spaces after `&` and `%` are ignored (real servers send them).
#include "stampscan/drivers/cmm/ipp_errors.hpp"
#include "stampscan/drivers/cmm/ipp_protocol.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <string>
#include <system_error>

namespace stampscan::drivers::cmm::ipp {

namespace {

bool isDigit(char c) { return c >= '0' && c <= '9'; }
bool isAlpha(char c) { return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z'); }
bool isLegalCharacter(char c) { return c >= 32 && c <= 126; }  // §6.1.1

// How a character is shown in an error message: printable as is, others as a hex escape.
std::string shown(char c) {
  if (isLegalCharacter(c)) return std::string("'") + c + "'";
  static constexpr char kHex[] = "0123456789abcdef";
  const auto u = static_cast<unsigned char>(c);
  return std::string("byte 0x") + kHex[u >> 4] + kHex[u & 0xf];
}

std::optional<Tag> tryTag(std::string_view text) {
  if (text.size() < 5) return std::nullopt;
  const bool event = text[0] == 'E';
  int number = 0;
  for (std::size_t i = event ? 1 : 0; i < 5; ++i) {
    if (!isDigit(text[i])) return std::nullopt;
    number = number * 10 + (text[i] - '0');
  }
  if (event) return Tag{Tag::Kind::Event, number};
  if (number == 0) return std::nullopt;  // 00000 is not a tag (§6.2.1)
  return Tag{Tag::Kind::Command, number};
}

// A position in one line; every failure names the 1-based column and what was found there.
class Cursor {
 public:
  Cursor(std::string_view line, std::size_t pos, std::optional<Tag> tag) : line_(line), pos_(pos), tag_(tag) {}

  [[noreturn]] void fail(const std::string& reason, int number = error::kProtocolError) const {
    throw ProtocolError(number, pos_ + 1, reason, line_, tag_);
  }
  [[noreturn]] void failExpected(const std::string& expected) const {
    fail("expected " + expected + ", found " + (atEnd() ? std::string("the end of the line") : shown(peek())));
  }

  bool atEnd() const { return pos_ >= line_.size(); }
  char peek() const { return line_[pos_]; }
  std::size_t pos() const { return pos_; }
  void skipSpaces() {
    while (!atEnd() && peek() == ' ') ++pos_;
  }
  bool accept(char c) {
    if (atEnd() || peek() != c) return false;
    ++pos_;
    return true;
  }
  void expect(char c, const char* what) {
    if (!accept(c)) failExpected(what);
  }
  void expectEnd(const char* after) {
    if (!atEnd()) fail(std::string("unexpected ") + shown(peek()) + " after " + after);
  }

  // Name :== BasicName { "." BasicName }, BasicName :== Alp {Alp | Num}
  std::string name() {
    const std::size_t start = pos_;
    for (;;) {
      if (atEnd() || !isAlpha(peek())) failExpected(pos_ == start ? "a name" : "a name after '.'");
      while (!atEnd() && (isAlpha(peek()) || isDigit(peek()))) ++pos_;
      if (!accept('.')) break;
    }
    return std::string(line_.substr(start, pos_ - start));
  }

  // Number :== ["+"|"-"]( (Num{Num}["."]{Num}) | ("."Num{Num}) )[Exponent], at most 16 digits.
  double number() {
    const std::size_t start = pos_;
    if (!atEnd() && (peek() == '+' || peek() == '-')) ++pos_;
    const auto digitRun = [this] {
      std::size_t count = 0;
      for (; !atEnd() && isDigit(peek()); ++pos_) ++count;
      return count;
    };
    std::size_t digits = digitRun();
    if (accept('.')) digits += digitRun();
    if (digits == 0) failExpected("a digit");
    if (digits > kMaxNumberDigits) {
      pos_ = start;
      fail("number has " + std::to_string(digits) + " digits, at most 16 are allowed");
    }
    if (!atEnd() && (peek() == 'E' || peek() == 'e')) {
      ++pos_;
      if (!atEnd() && (peek() == '+' || peek() == '-')) ++pos_;
      const std::size_t exponent_digits = digitRun();
      if (exponent_digits == 0) failExpected("a digit in the exponent");
      if (exponent_digits > 3) {
        pos_ = start;
        fail("exponent has more than 3 digits");
      }
    }
    const std::string_view spelled = line_.substr(start, pos_ - start);
    const std::string_view text = spelled.front() == '+' ? spelled.substr(1) : spelled;  // from_chars takes no '+'
    double value = 0;
    const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
    if (ec != std::errc() || end != text.data() + text.size() || !std::isfinite(value)) {
      pos_ = start;
      fail("number " + std::string(spelled) + " is out of range");
    }
    return value;
  }

  // String :== q Char {Char} q. An empty string is accepted (some servers send one).
  std::string string() {
    expect('"', "'\"'");
    const std::size_t start = pos_;
    while (!atEnd() && peek() != '"') ++pos_;
    if (atEnd()) {
      pos_ = start - 1;
      fail("string is not closed by '\"'");
    }
    std::string text(line_.substr(start, pos_ - start));
    ++pos_;
    return text;
  }

  // Argument :== String | Number | Property | ETag | BasicName; properties may nest (GoTo(X(1))).
  Argument argument(std::size_t depth) {
    const std::size_t column = pos_ + 1;
    if (atEnd()) failExpected("an argument");
    const char c = peek();
    Argument result;
    if (c == '"') {
      result = Argument::str(string());
    } else if (isDigit(c) || c == '+' || c == '-' || c == '.') {
      result = Argument::num(number());
    } else if (isAlpha(c)) {
      std::string text = name();
      skipSpaces();
      if (!atEnd() && peek() == '(') {
        result = Argument::call(std::move(text), argumentList(depth + 1));
      } else if (text.find('.') != std::string::npos) {
        failExpected("'(' after the property name " + text);
      } else {
        result = Argument::name(std::move(text));
      }
    } else {
      failExpected("an argument (a number, a \"string\", a name or a property)");
    }
    result.column = column;
    return result;
  }

  // SLeftParenS [Argument {SCommaS Argument}] SRightParen
  std::vector<Argument> argumentList(std::size_t depth) {
    if (depth > kMaxArgumentDepth) fail("arguments nested deeper than " + std::to_string(kMaxArgumentDepth));
    expect('(', "'('");
    skipSpaces();
    std::vector<Argument> args;
    if (accept(')')) return args;
    for (;;) {
      args.push_back(argument(depth));
      skipSpaces();
      if (accept(')')) return args;
      if (!accept(',')) failExpected("',' or ')'");
      skipSpaces();
    }
  }

  // Argument {SCommaS Argument} up to the end of the line (the data of a `#` response).
  std::vector<Argument> argumentsToEnd() {
    std::vector<Argument> args;
    for (;;) {
      args.push_back(argument(1));
      skipSpaces();
      if (atEnd()) return args;
      if (!accept(',')) failExpected("',' or the end of the line");
      skipSpaces();
    }
  }

 private:
  std::string_view line_;
  std::size_t pos_;
  std::optional<Tag> tag_;
};

// §6.1.1: only ASCII 32..126 on the wire apart from the terminating CR LF.
void checkCharacters(std::string_view line, std::optional<Tag> tag) {
  for (std::size_t i = 0; i < line.size(); ++i) {
    if (!isLegalCharacter(line[i])) {
      throw ProtocolError(error::kIllegalCharacter, i + 1,
                          shown(line[i]) + " is not allowed (only ASCII 32..126, lines end in CR LF)", line, tag);
    }
  }
}

// The tag in columns 1-5 and the space in column 6 (§6.2.2.1, §6.2.2.2).
Tag lineTag(std::string_view line, bool allow_server_event) {
  const std::optional<Tag> tag = tryTag(line);
  checkCharacters(line, tag);
  if (!tag || (tag->isServerEvent() && !allow_server_event)) {
    std::size_t column = 1;  // the first offending character
    while (column <= 5 && column <= line.size()) {
      const char c = line[column - 1];
      if (column == 1 ? !(isDigit(c) || c == 'E') : !isDigit(c)) break;
      ++column;
    }
    const std::string found(line.substr(0, 5));
    throw ProtocolError(error::kIllegalTag, std::min(column, std::size_t{5}),
                        "tag \"" + found + "\" is not 00001-99999 or E0001-E9999", line);
  }
  if (line.size() < 6 || line[5] != ' ') {
    throw ProtocolError(error::kNoSpaceAtPos6, 6, "expected a space after the tag in column 6", line, tag);
  }
  return *tag;
}

bool isInteger(const Argument& a, int low, int high) {
  return a.kind == Argument::Kind::Number && a.number >= low && a.number <= high && std::floor(a.number) == a.number;
}

// `Error(F1, F2, F3, Text)` (§6.1.4.2 ErrorResponse, §8.1). F3 may come quoted (the grammar) or bare
// (the examples, and §8.1: "no need for putting into quotes"). F2 may have fewer than 4 digits, as
// in the example of §6.2.4.1.
ErrorReport errorReport(Cursor& cursor) {
  const std::size_t start = cursor.pos();
  const std::string keyword = cursor.name();
  if (keyword != "Error") {
    throw ProtocolError(error::kProtocolError, start + 1, "expected Error(...) after '!', found " + keyword, "",
                        std::nullopt);
  }
  cursor.skipSpaces();
  const std::vector<Argument> f = cursor.argumentList(1);
  cursor.expectEnd("Error(...)");
  const auto bad = [&](std::size_t column, const std::string& reason) -> ProtocolError {
    return ProtocolError(error::kProtocolError, column, reason, "", std::nullopt);
  };
  if (f.size() != 4) throw bad(start + 1, "Error(...) needs 4 fields (class, number, method, text), has " +
                                              std::to_string(f.size()));
  if (!isInteger(f[0], 0, 9)) throw bad(f[0].column, "error class must be a digit 0-9");
  if (!isInteger(f[1], 0, 9999)) throw bad(f[1].column, "error number must be an integer 0-9999");
  if (f[2].kind != Argument::Kind::String && f[2].kind != Argument::Kind::Name) {
    throw bad(f[2].column, "error method must be a name or a string");
  }
  if (f[3].kind != Argument::Kind::String) throw bad(f[3].column, "error text must be a string");
  return {static_cast<int>(f[0].number), static_cast<int>(f[1].number), f[2].text, f[3].text};
}

}  // namespace

Tag parseTag(std::string_view text) {
  const std::optional<Tag> tag = text.size() == 5 ? tryTag(text) : std::nullopt;
  if (!tag) throw ProtocolError(error::kIllegalTag, 1, "\"" + std::string(text.substr(0, 16)) + "\" is not a tag", text);
  return *tag;
}

Command parseCommand(std::string_view line) {
  // E0000 belongs to the server (§6.2.1 ETag excludes it).
  const Tag tag = lineTag(line, false);
  Cursor cursor(line, 6, tag);
  Command command{tag, cursor.name(), {}};  // §6.2.2.1: the command starts at column 7
  cursor.skipSpaces();
  command.args = cursor.argumentList(1);
  cursor.expectEnd("the closing ')' of the command");
  return command;
}

Reply parseReply(std::string_view line) {
  const Tag tag = lineTag(line, true);
  Cursor cursor(line, 6, tag);
  if (cursor.atEnd()) cursor.failExpected("&, %, # or ! in column 7");
  const char kind = cursor.peek();
  if (kind != '&' && kind != '%' && kind != '#' && kind != '!') cursor.failExpected("&, %, # or ! in column 7");
  cursor.accept(kind);
  if (kind == '&' || kind == '%') {
    cursor.skipSpaces();
    cursor.expectEnd(std::string(1, kind).c_str());
    return kind == '&' ? Reply::ack(tag) : Reply::complete(tag);
  }
  cursor.expect(' ', "a space in column 8");  // §6.2.2.2
  cursor.skipSpaces();
  if (kind == '#') return Reply::dataLine(tag, cursor.argumentsToEnd());
  try {
    return Reply::errorLine(tag, errorReport(cursor));
  } catch (const ProtocolError& e) {
    // errorReport() builds its errors without the line; add it here.
    throw ProtocolError(e.errorNumber(), e.column(), e.reason(), line, tag);
  }
}

std::vector<Argument> parseArguments(std::string_view text) {
  checkCharacters(text, std::nullopt);
  Cursor cursor(text, 0, std::nullopt);
  cursor.skipSpaces();
  return cursor.argumentsToEnd();
}

}  // namespace stampscan::drivers::cmm::ipp
