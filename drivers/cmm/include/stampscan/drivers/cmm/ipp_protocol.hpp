// The I++ DME wire format (spec 1.4.3, /work/shared/reference/ipp-dme-1.4.3-spec.txt), shared by the
// CMM driver and the virtual CMM in sim/: CR LF line framing (§6.1.1, §6.2), tags (§6.2.1), command
// lines `TAG Name(args)` and response lines `TAG &`, `TAG %`, `TAG # data`, `TAG ! Error(...)`
// (§6.1.4.2, §6.2.2). Everything here is pure: no sockets, no threads.
//
// The parsers take untrusted input (whatever arrives on port 1294) and are fuzzed: on bad input they
// throw ProtocolError naming the column and the offending text, never anything else, never crash.
#pragma once

#include <compare>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace stampscan::drivers::cmm::ipp {

inline constexpr std::uint16_t kDefaultPort = 1294;       // §6.1
inline constexpr std::size_t kMaxLineLength = 65536;      // §6.2, without the CR LF
inline constexpr std::size_t kMaxNumberDigits = 16;       // §6.1.4.2, Number
inline constexpr std::size_t kMaxArgumentDepth = 8;       // ours: GoTo(X(1)) needs 2, bounds recursion

// A command tag 00001-99999 or an event tag E0001-E9999; E0000 is the server's own event tag
// (§6.2.1, §4.4). Ordered so it can key a map.
struct Tag {
  enum class Kind { Command, Event };
  Kind kind = Kind::Command;
  int number = 1;

  static Tag command(int number);  // throws std::invalid_argument outside 1..99999
  static Tag event(int number);    // throws std::invalid_argument outside 0..9999
  static Tag serverEvent() { return {Kind::Event, 0}; }

  bool isEvent() const { return kind == Kind::Event; }
  bool isServerEvent() const { return kind == Kind::Event && number == 0; }
  std::string str() const;  // "00042", "E0553"
  auto operator<=>(const Tag&) const = default;
};

// One argument of a method, or one item of a data response: a Number, a String (without its
// quotes), a bare Name (an enum like MachineCsy or an event tag like E0553), or a Call such as
// X(100) or Tool.GoToPar.Speed() with its own arguments (§6.1.4.2, Property and Method).
struct Argument {
  enum class Kind { Number, String, Name, Call };
  Kind kind = Kind::Number;
  double number = 0;               // Number
  std::string text;                // String contents, Name, or the Call's name
  std::vector<Argument> args;      // Call
  std::size_t column = 0;          // 1-based column where it started, 0 when built in code

  static Argument num(double value);
  static Argument str(std::string value);
  static Argument name(std::string value);
  static Argument call(std::string name, std::vector<Argument> args = {});

  bool isCall(std::string_view call_name) const { return kind == Kind::Call && text == call_name; }
  // Compares content, not where it was found.
  bool operator==(const Argument& other) const;
};

struct Command {
  Tag tag;
  std::string name;  // "GoTo", "OnMoveReportE", ...
  std::vector<Argument> args;
  bool operator==(const Command& other) const = default;
};

// The fields of `! Error(F1, F2, F3, Text)` (§8.1).
struct ErrorReport {
  int severity = 3;     // F1: 0 info, 1 warning, 2 client can repair, 3 user needed, 9 fatal
  int number = 0;       // F2: the error number of §8.2
  std::string method;   // F3: the method that failed
  std::string text;     // the text of §8.2 for that number
  bool operator==(const ErrorReport& other) const = default;
};

enum class ReplyKind { Ack, Complete, Data, Error };  // & % # ! (§6.2.2.3)
char toChar(ReplyKind kind);

struct Reply {
  Tag tag;
  ReplyKind kind = ReplyKind::Ack;
  std::vector<Argument> data;  // Data only
  ErrorReport error;           // Error only
  bool operator==(const Reply& other) const = default;

  static Reply ack(Tag tag) { return {tag, ReplyKind::Ack, {}, {}}; }
  static Reply complete(Tag tag) { return {tag, ReplyKind::Complete, {}, {}}; }
  static Reply dataLine(Tag tag, std::vector<Argument> data) { return {tag, ReplyKind::Data, std::move(data), {}}; }
  static Reply errorLine(Tag tag, ErrorReport error) { return {tag, ReplyKind::Error, {}, std::move(error)}; }
};

// Bad input on the wire. errorNumber() is the §8.2 number a server answers with: 0001 bad tag,
// 0002 no space at column 6, 0007 illegal character, 0008 any other syntax error.
class ProtocolError : public std::runtime_error {
 public:
  ProtocolError(int error_number, std::size_t column, const std::string& reason, std::string_view line,
                std::optional<Tag> tag = {});
  int errorNumber() const { return error_number_; }
  std::size_t column() const { return column_; }  // 1-based
  const std::string& reason() const { return reason_; }
  const std::optional<Tag>& tag() const { return tag_; }  // the line's tag, when it could be read

 private:
  int error_number_;
  std::size_t column_;
  std::string reason_;
  std::optional<Tag> tag_;
};

// Parsers: one line without its CR LF. Throw ProtocolError and nothing else.
Tag parseTag(std::string_view text);  // exactly 5 characters
Command parseCommand(std::string_view line);
Reply parseReply(std::string_view line);
// A comma-separated list of arguments, e.g. the data of a `#` response.
std::vector<Argument> parseArguments(std::string_view text);

// Formatters: one line without its CR LF. Throw std::invalid_argument for what the grammar cannot
// carry (a non-finite number, a `"` or a control character in a string, an empty name).
std::string formatNumber(double value);  // shortest text that reads back to the same double
std::string formatArgument(const Argument& argument);
std::string formatArguments(const std::vector<Argument>& arguments);  // "X(1), Y(2)"
std::string formatCommand(const Command& command);
std::string formatReply(const Reply& reply);
// Makes free text safe for a String: `"` becomes `'`, characters outside 32..126 become `?`.
std::string sanitizeText(std::string_view text);

// Splits a byte stream into lines at CR LF (§6.1.1). A bare LF still ends a line, flagged, so that a
// netcat user gets error 0007 rather than silence; an over-long line is cut off and flagged.
class LineFramer {
 public:
  enum class Problem { None, MissingCr, TooLong };
  struct Line {
    std::string text;  // without the terminator
    Problem problem = Problem::None;
  };

  explicit LineFramer(std::size_t max_line_length = kMaxLineLength) : max_(max_line_length) {}
  void append(std::string_view bytes) { buffer_.append(bytes); }
  std::optional<Line> next();
  std::size_t pendingBytes() const { return buffer_.size(); }

 private:
  std::size_t max_;
  std::string buffer_;
  std::size_t scanned_ = 0;  // bytes of buffer_ already searched for LF
  bool discarding_ = false;  // inside an over-long line, dropping bytes up to its end
};

// A line ready to send: the text followed by CR LF.
std::string frameLine(std::string_view line);

}  // namespace stampscan::drivers::cmm::ipp
