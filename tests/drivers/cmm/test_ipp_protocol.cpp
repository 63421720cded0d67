// The I++ DME codec: the spec's own example lines, round trips, numbers, malformed lines (error
// number and column), line framing and the error table.
#include "stampscan/drivers/cmm/ipp_errors.hpp"
#include "stampscan/drivers/cmm/ipp_protocol.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <set>

namespace stampscan::drivers::cmm::ipp {
namespace {

using A = Argument;

TEST(IppTag, FormatsAndParses) {
  EXPECT_EQ(Tag::command(1).str(), "00001");
  EXPECT_EQ(Tag::command(99999).str(), "99999");
  EXPECT_EQ(Tag::event(553).str(), "E0553");
  EXPECT_EQ(Tag::serverEvent().str(), "E0000");
  EXPECT_EQ(parseTag("04711"), Tag::command(4711));
  EXPECT_EQ(parseTag("E3333"), Tag::event(3333));
  // §6.2.1's own examples of bad tags.
  for (const char* bad : {"00000", "20", "E20", "A4711", "0001x", "000001"}) {
    EXPECT_THROW(parseTag(bad), ProtocolError) << bad;
  }
  EXPECT_THROW(Tag::command(0), std::invalid_argument);
  EXPECT_THROW(Tag::command(100000), std::invalid_argument);
  EXPECT_THROW(Tag::event(10000), std::invalid_argument);
}

// Lines from the spec's examples (§6.2.3.1, §6.2.4.1, §6.3.1.7, §7) parse as written there.
TEST(IppCommand, ParsesTheSpecExamples) {
  const Command go = parseCommand("00002 GoTo(X(100))");
  EXPECT_EQ(go.tag, Tag::command(2));
  EXPECT_EQ(go.name, "GoTo");
  ASSERT_EQ(go.args.size(), 1u);
  EXPECT_EQ(go.args[0], A::call("X", {A::num(100)}));
  EXPECT_EQ(go.args[0].column, 12u);

  const Command report = parseCommand("E0553 OnMoveReportE(Time(1),Dis(20),X(), Y(), Z())");
  EXPECT_TRUE(report.tag.isEvent());
  EXPECT_EQ(report.args, (std::vector<A>{A::call("Time", {A::num(1)}), A::call("Dis", {A::num(20)}), A::call("X"),
                                         A::call("Y"), A::call("Z")}));
  EXPECT_EQ(parseCommand("00049 StopDaemon(E0553)").args, std::vector<A>{A::name("E0553")});
  EXPECT_EQ(parseCommand("00015 SetProp(Tool.PtMeasPar.Speed(100))").args[0].text, "Tool.PtMeasPar.Speed");
  EXPECT_EQ(parseCommand("00016 FindTool(\"Probe1\")").args, std::vector<A>{A::str("Probe1")});
  EXPECT_EQ(parseCommand("00010 SetCoordSystem(PartCsy)").args, std::vector<A>{A::name("PartCsy")});
  EXPECT_TRUE(parseCommand("00001 StartSession()").args.empty());
}

TEST(IppCommand, AcceptsSpacesOnlyWhereTheGrammarDoes) {
  // §6.1.4.2: spaces around commas, around '(' and before ')'.
  const Command spaced = parseCommand("00001 GoTo ( X( 1 ) ,  Y(2)   )");
  EXPECT_EQ(spaced.args, (std::vector<A>{A::call("X", {A::num(1)}), A::call("Y", {A::num(2)})}));
  EXPECT_THROW(parseCommand("00001  GoTo(X(1))"), ProtocolError);  // two spaces after the tag
  EXPECT_THROW(parseCommand("00001 GoTo(X(1)) "), ProtocolError);  // after the final ')'
  EXPECT_THROW(parseCommand("00001 GoTo(X (1) Y(2))"), ProtocolError);
}

TEST(IppCommand, RoundTrips) {
  const std::vector<Command> commands{
      {Tag::command(1), "StartSession", {}},
      {Tag::command(42), "GoTo", {A::call("X", {A::num(-12.5)}), A::call("Y", {A::num(0.001)}), A::call("Z", {A::num(1e-7)})}},
      {Tag::event(9999), "OnMoveReportE", {A::call("Time", {A::num(0.1)}), A::call("X"), A::call("SS.Time")}},
      {Tag::command(99999), "ChangeTool", {A::str("Probe 1 (long) #2")}},
      {Tag::command(7), "StopDaemon", {A::name("E0553")}},
      {Tag::command(8), "ScanOnCurve", {A::call("Closed", {A::num(0)}), A::call("Format", {A::call("X"), A::call("Y")})}},
  };
  for (const Command& c : commands) {
    const std::string line = formatCommand(c);
    EXPECT_EQ(parseCommand(line), c) << line;
  }
  EXPECT_EQ(formatCommand(commands[1]), "00042 GoTo(X(-12.5), Y(0.001), Z(1e-07))");
}

TEST(IppReply, ParsesTheSpecExamples) {
  EXPECT_EQ(parseReply("00001 &"), Reply::ack(Tag::command(1)));
  EXPECT_EQ(parseReply("00001 %"), Reply::complete(Tag::command(1)));
  EXPECT_EQ(parseReply("00002 & "), Reply::ack(Tag::command(2)));  // trailing spaces seen in the field
  EXPECT_EQ(parseReply("00004 # X(99.93), Y(17.148)").data,
            (std::vector<A>{A::call("X", {A::num(99.93)}), A::call("Y", {A::num(17.148)})}));
  EXPECT_EQ(parseReply("00014 # \"Speed\", \"Number\"").data, (std::vector<A>{A::str("Speed"), A::str("Number")}));
  EXPECT_EQ(parseReply("00051 # DMEVersion(\"1.4\")").data[0], A::call("DMEVersion", {A::str("1.4")}));
  EXPECT_EQ(parseReply("00015 # Tool.PtMeasPar.Speed(100), Tool.PtMeasPar.Retract(2.0)").data.size(), 2u);

  const Reply limit = parseReply("00003 ! Error(3, 2500, GoTo, \"Machine limit encountered (Move Out Of Limits)\")");
  EXPECT_EQ(limit.kind, ReplyKind::Error);
  EXPECT_EQ(limit.error, (ErrorReport{3, 2500, "GoTo", "Machine limit encountered (Move Out Of Limits)"}));
  const Reply estop = parseReply("E0000 ! Error(3, 500, HealthCheck, \"Emergency Stop\")");
  EXPECT_TRUE(estop.tag.isServerEvent());
  EXPECT_EQ(estop.error.number, 500);
  EXPECT_EQ(parseReply("00051 ! Error(2,0006,GoTo,\"Transaction aborted\")").error.number, 6);
}

TEST(IppReply, RoundTrips) {
  const std::vector<Reply> replies{
      Reply::ack(Tag::command(5)),
      Reply::complete(Tag::event(12)),
      Reply::dataLine(Tag::command(6), {A::call("X", {A::num(1.5)}), A::call("Y", {A::num(-2)}), A::call("Z", {A::num(3e5)})}),
      Reply::dataLine(Tag::command(7), {A::str("RefTool")}),
      Reply::dataLine(Tag::command(8), {A::call("Tool.Name", {A::str("Probe1")})}),
      Reply::errorLine(Tag::command(9), makeError(error::kMachineLimit, "GoTo")),
      Reply::errorLine(Tag::serverEvent(), makeError(error::kIllegalTag, "CommandLine")),
  };
  for (const Reply& r : replies) {
    const std::string line = formatReply(r);
    EXPECT_EQ(parseReply(line), r) << line;
  }
  EXPECT_EQ(formatReply(replies[5]), "00009 ! Error(3, 2500, \"GoTo\", \"Machine limit encountered [Move Out Of Limits]\")");
  EXPECT_EQ(formatReply(replies[0]), "00005 &");
}

TEST(IppNumber, ShortestTextReadsBackExactly) {
  std::mt19937_64 random(1294);
  std::uniform_real_distribution<double> mantissa(-1, 1);
  std::uniform_int_distribution<int> exponent(-300, 300);
  std::vector<double> values{0.1 + 0.2, 1.0 / 3, -123.456, 1e-300, 1e300, 5e-324, 1.7976931348623157e308, 4096, -0.0};
  for (int i = 0; i < 2000; ++i) values.push_back(mantissa(random) * std::pow(10.0, exponent(random)));
  for (const double v : values) {
    const std::string text = formatNumber(v);
    const Command c = parseCommand("00001 GoTo(X(" + text + "))");
    const double back = c.args[0].args[0].number;
    std::size_t digits = 0;
    for (const char ch : text.substr(0, text.find('e'))) digits += (ch >= '0' && ch <= '9') ? 1 : 0;
    EXPECT_LE(digits, kMaxNumberDigits) << text;
    // 16 digits carry a double to within one part in 1e16; most need fewer and come back exact.
    EXPECT_NEAR(back, v, std::abs(v) * 1e-15) << text;
  }
  EXPECT_EQ(formatNumber(100), "100");
  EXPECT_EQ(formatNumber(0.5), "0.5");
  EXPECT_THROW(formatNumber(std::numeric_limits<double>::infinity()), std::invalid_argument);
  EXPECT_THROW(formatNumber(std::nan("")), std::invalid_argument);
  // The number syntax of §6.1.4.2.
  for (const char* good : {"1", "+1", "-1.", ".5", "1.5e3", "1E-3", "1.7e+308", "0000000000000001"}) {
    EXPECT_NO_THROW(parseCommand(std::string("00001 GoTo(X(") + good + "))")) << good;
  }
}

struct Malformed {
  const char* line;
  int error_number;
  std::size_t column;
  const char* reason_part;
};

TEST(IppCommand, RejectsMalformedLinesNamingColumnAndReason) {
  const std::vector<Malformed> cases{
      {"", error::kIllegalTag, 1, "is not 00001-99999"},
      {"0001 Home()", error::kIllegalTag, 5, "tag \"0001 \""},
      {"00000 Home()", error::kIllegalTag, 5, "tag"},
      {"E0000 Home()", error::kIllegalTag, 5, "tag"},
      {"X0001 Home()", error::kIllegalTag, 1, "tag"},
      {"00001Home()", error::kNoSpaceAtPos6, 6, "space"},
      {"00001", error::kNoSpaceAtPos6, 6, "space"},
      {"00001 Home(", error::kProtocolError, 12, "expected an argument"},
      {"00001 Home", error::kProtocolError, 11, "expected '('"},
      {"00001 GoTo(X(1)", error::kProtocolError, 16, "expected ',' or ')'"},
      {"00001 GoTo(X(1)))", error::kProtocolError, 17, "unexpected ')'"},
      {"00001 Home() ", error::kProtocolError, 13, "unexpected ' '"},
      {"00001 GoTo(X(1,))", error::kProtocolError, 16, "expected an argument"},
      {"00001 GoTo(X(12345678901234567))", error::kProtocolError, 14, "17 digits"},
      {"00001 GoTo(X(1e1000))", error::kProtocolError, 14, "exponent"},
      {"00001 GoTo(X(1e400))", error::kProtocolError, 14, "out of range"},
      {"00001 GoTo(X(1e))", error::kProtocolError, 16, "digit in the exponent"},
      {"00001 GoTo(X(--1))", error::kProtocolError, 15, "expected a digit"},
      {"00001 GoTo(X(.))", error::kProtocolError, 15, "expected a digit"},
      {"00001 ChangeTool(\"Probe1)", error::kProtocolError, 18, "not closed"},
      {"00001 Tool.(1)", error::kProtocolError, 12, "name after '.'"},
      {"00001 1Home()", error::kProtocolError, 7, "expected a name"},
      {"00001 GoTo(Tool.GoToPar)", error::kProtocolError, 24, "'(' after the property name"},
      {"00001 GoTo(X(1)\x01)", error::kIllegalCharacter, 16, "byte 0x01"},
      {"00001 Home()\r", error::kIllegalCharacter, 13, "byte 0x0d"},
      {"0\x80" "001 Home()", error::kIllegalCharacter, 2, "byte 0x80"},
  };
  for (const Malformed& m : cases) {
    try {
      parseCommand(m.line);
      ADD_FAILURE() << "accepted: " << m.line;
    } catch (const ProtocolError& e) {
      EXPECT_EQ(e.errorNumber(), m.error_number) << m.line << ": " << e.what();
      EXPECT_EQ(e.column(), m.column) << m.line << ": " << e.what();
      EXPECT_NE(e.reason().find(m.reason_part), std::string::npos) << m.line << ": " << e.what();
      EXPECT_NE(std::string(e.what()).find("column " + std::to_string(m.column)), std::string::npos) << e.what();
    }
  }
  // The tag travels with the error whenever it was readable, so a server can answer on it.
  try {
    parseCommand("00017 GoTo(X(1)");
  } catch (const ProtocolError& e) {
    ASSERT_TRUE(e.tag().has_value());
    EXPECT_EQ(*e.tag(), Tag::command(17));
  }
  std::string deep = "00001 A(";
  for (int i = 0; i < 20; ++i) deep += "B(";
  deep += std::string(21, ')');
  EXPECT_THROW(parseCommand(deep), ProtocolError);
}

TEST(IppReply, RejectsMalformedLines) {
  const std::vector<Malformed> cases{
      {"00001 ?", error::kProtocolError, 7, "&, %, # or !"},
      {"00001 ", error::kProtocolError, 7, "&, %, # or !"},
      {"00001 #", error::kProtocolError, 8, "space in column 8"},
      {"00001 # ", error::kProtocolError, 9, "expected an argument"},
      {"00001 & x", error::kProtocolError, 9, "unexpected 'x'"},
      {"00001 ! Error(3, 2500, GoTo)", error::kProtocolError, 9, "needs 4 fields"},
      {"00001 ! Error(12, 2500, GoTo, \"x\")", error::kProtocolError, 15, "class"},
      {"00001 ! Error(3, 2500.5, GoTo, \"x\")", error::kProtocolError, 18, "error number"},
      {"00001 ! Error(3, 2500, GoTo, 5)", error::kProtocolError, 30, "text must be a string"},
      {"00001 ! Warning(3, 2500, GoTo, \"x\")", error::kProtocolError, 9, "expected Error"},
      {"00001 # X(1) Y(2)", error::kProtocolError, 14, "',' or the end"},
  };
  for (const Malformed& m : cases) {
    try {
      parseReply(m.line);
      ADD_FAILURE() << "accepted: " << m.line;
    } catch (const ProtocolError& e) {
      EXPECT_EQ(e.errorNumber(), m.error_number) << m.line << ": " << e.what();
      EXPECT_EQ(e.column(), m.column) << m.line << ": " << e.what();
      EXPECT_NE(e.reason().find(m.reason_part), std::string::npos) << m.line << ": " << e.what();
    }
  }
}

TEST(IppFormat, RefusesWhatTheGrammarCannotCarry) {
  EXPECT_THROW(formatArgument(A::str("say \"hi\"")), std::invalid_argument);
  EXPECT_THROW(formatArgument(A::str("tab\there")), std::invalid_argument);
  EXPECT_THROW(formatArgument(A::name("1abc")), std::invalid_argument);
  EXPECT_THROW(formatArgument(A::call("Tool.")), std::invalid_argument);
  EXPECT_THROW(formatCommand({Tag::command(1), "", {}}), std::invalid_argument);
  EXPECT_THROW(formatReply(Reply::dataLine(Tag::command(1), {})), std::invalid_argument);
  EXPECT_EQ(sanitizeText("a \"b\"\tc"), "a 'b'?c");
}

TEST(IppLineFramer, SplitsAtCrLfAcrossChunks) {
  LineFramer framer;
  const std::string stream = "00001 &\r\n00001 %\r\n00002 # X(1)\r\n";
  for (const char c : stream) framer.append(std::string_view(&c, 1));  // the worst case: byte by byte
  std::vector<std::string> lines;
  while (auto line = framer.next()) {
    EXPECT_EQ(line->problem, LineFramer::Problem::None);
    lines.push_back(line->text);
  }
  EXPECT_EQ(lines, (std::vector<std::string>{"00001 &", "00001 %", "00002 # X(1)"}));
  EXPECT_EQ(framer.pendingBytes(), 0u);
  EXPECT_EQ(frameLine("00001 &"), "00001 &\r\n");
}

TEST(IppLineFramer, FlagsBareLfAndOverlongLines) {
  LineFramer framer(16);
  framer.append("00001 Home()\n");
  auto line = framer.next();
  ASSERT_TRUE(line);
  EXPECT_EQ(line->problem, LineFramer::Problem::MissingCr);
  EXPECT_EQ(line->text, "00001 Home()");

  framer.append("00002 GoTo(X(1), Y(2), Z(3))");  // longer than 16, no end yet: reported at once
  line = framer.next();
  ASSERT_TRUE(line);
  EXPECT_EQ(line->problem, LineFramer::Problem::TooLong);
  EXPECT_EQ(line->text, "00002 GoTo(X(1),");
  framer.append(" and more\r\n00003 Home()\r\n");  // the rest of the long line is dropped
  line = framer.next();
  ASSERT_TRUE(line);
  EXPECT_EQ(line->problem, LineFramer::Problem::None);
  EXPECT_EQ(line->text, "00003 Home()");
  EXPECT_FALSE(framer.next());
}

TEST(IppErrors, FollowTheSpecList) {
  const ErrorReport limit = makeError(2500, "GoTo");
  EXPECT_EQ(limit.severity, 3);
  EXPECT_EQ(limit.text, "Machine limit encountered [Move Out Of Limits]");
  EXPECT_EQ(makeError(504, "SetProp").severity, 1);
  EXPECT_EQ(makeError(6, "GoTo").severity, 2);
  EXPECT_EQ(makeError(503, "x").severity, 9);
  EXPECT_EQ(findError(4242), nullptr);
  EXPECT_EQ(makeError(4242, "x").text, "Unknown error");
  EXPECT_EQ(describe(limit), "I++ DME error 2500 (class 3) in GoTo: Machine limit encountered [Move Out Of Limits]");
  EXPECT_FALSE(needsClearAllErrors(1));
  EXPECT_TRUE(needsClearAllErrors(2));
  std::set<int> numbers;
  for (int n = 0; n < 10000; ++n) {
    if (const ErrorDefinition* d = findError(n)) {
      EXPECT_EQ(d->number, n);
      numbers.insert(n);
      EXPECT_NO_THROW(formatReply(Reply::errorLine(Tag::command(1), makeError(n, "M"))));
    }
  }
  EXPECT_EQ(numbers.size(), 52u);
}

}  // namespace
}  // namespace stampscan::drivers::cmm::ipp
