// Reading and writing robot data files: exact round trips, one test per error case (with the
// exact line and column it must report), atomic writes that leave the old file intact, and the
// real data sets.

#include <signal.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <iterator>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <zlib.h>

#include "temp_files.h"
#include "structgp/io/csv.h"

namespace structgp {
namespace {

namespace fs = std::filesystem;

struct TempDir : testing::TempDir {
  TempDir() : testing::TempDir("test_csv") {}
};

void WriteBytes(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary);
  out << bytes;
  ASSERT_TRUE(out.good()) << path;
}

std::string ReadBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

void WriteGzip(const std::string& path, const std::string& bytes) {
  gzFile file = gzopen(path.c_str(), "wb");
  ASSERT_NE(file, nullptr) << path;
  ASSERT_EQ(gzwrite(file, bytes.data(), static_cast<unsigned>(bytes.size())),
            static_cast<int>(bytes.size()));
  ASSERT_EQ(gzclose(file), Z_OK);
}

// The DataError that reading `path` throws (a failure is recorded when it throws none).
DataError ReadError(const std::string& path, const CsvOptions& options = {}) {
  try {
    ReadRobotCsv(path, options);
  } catch (const DataError& error) {
    return error;
  }
  ADD_FAILURE() << "reading " << path << " did not throw DataError";
  return DataError(path, 0, 0, "(no error)");
}

// Checks where the error points and that its message holds every word of `words`.
void ExpectError(const DataError& error, const std::string& path, int line, int column,
                 std::initializer_list<const char*> words) {
  EXPECT_EQ(error.file(), path);
  EXPECT_EQ(error.line(), line) << error.what();
  EXPECT_EQ(error.column(), column) << error.what();
  for (const char* word : words) {
    EXPECT_NE(error.message().find(word), std::string::npos)
        << "message lacks \"" << word << "\": " << error.what();
  }
  std::string prefix = path + ":";
  if (line > 0) prefix += std::to_string(line) + ":";
  if (line > 0 && column > 0) prefix += std::to_string(column) + ":";
  EXPECT_EQ(std::string(error.what()), prefix + " " + error.message());
}

// Reads a CSV given as text and returns the error it raises.
class CsvErrorTest : public ::testing::Test {
 protected:
  DataError ErrorFor(const std::string& text, const CsvOptions& options = {}) {
    WriteBytes(path_, text);
    return ReadError(path_, options);
  }
  TempDir dir_;
  std::string path_ = dir_.File("data.csv");
};

RobotData RandomRobotData(int num_joints, int rows, bool with_time, unsigned seed) {
  std::mt19937 generator(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_int_distribution<int> exponent(-12, 5);
  RobotData data;
  data.num_joints = num_joints;
  data.X.resize(rows, 3 * num_joints);
  data.Y.resize(rows, num_joints);
  // Values over many orders of magnitude, so that every digit counts.
  for (int i = 0; i < rows; ++i) {
    for (int j = 0; j < 3 * num_joints; ++j) data.X(i, j) = normal(generator) * std::pow(10.0, exponent(generator));
    for (int j = 0; j < num_joints; ++j) data.Y(i, j) = normal(generator) * std::pow(10.0, exponent(generator));
  }
  if (with_time) {
    data.t.resize(rows);
    for (int i = 0; i < rows; ++i) data.t(i) = 0.008 * i + 1.7e9;  // Unix time stamps.
  }
  return data;
}

// ---- DataError --------------------------------------------------------------------------------

TEST(DataErrorTest, WhatReadsLikeACompilerDiagnostic) {
  EXPECT_STREQ(DataError("a.csv", 3, 7, "bad cell").what(), "a.csv:3:7: bad cell");
  EXPECT_STREQ(DataError("a.csv", 3, 0, "bad line").what(), "a.csv:3: bad line");
  EXPECT_STREQ(DataError("a.csv", 0, 0, "bad file").what(), "a.csv: bad file");
  // A column without a line means nothing: it is dropped.
  const DataError error("a.csv", 0, 5, "bad file");
  EXPECT_STREQ(error.what(), "a.csv: bad file");
  EXPECT_EQ(error.column(), 0);
  EXPECT_EQ(error.message(), "bad file");
}

// ---- Round trips ------------------------------------------------------------------------------

TEST(CsvRoundTripTest, WriteThenReadIsExact) {
  TempDir dir;
  for (const bool with_time : {false, true}) {
    const unsigned seed = with_time ? 11u : 7u;
    SCOPED_TRACE("seed " + std::to_string(seed));
    RobotData data = RandomRobotData(3, 40, with_time, seed);
    data.X(0, 0) = 0.1;
    data.X(1, 1) = 1.0 / 3.0;
    data.X(2, 2) = -0.0;
    data.Y(3, 0) = 4.9406564584124654e-324;  // Smallest subnormal.
    data.Y(4, 1) = 999999.99999999988;       // Just under the default max_abs.
    const std::string path = dir.File(with_time ? "with_t.csv" : "without_t.csv");
    WriteRobotCsv(path, data);
    const RobotData read = ReadRobotCsv(path);
    EXPECT_EQ(read.num_joints, 3);
    EXPECT_EQ(read.has_time(), with_time);
    ASSERT_EQ(read.size(), 40);
    EXPECT_TRUE((read.X.array() == data.X.array()).all());
    EXPECT_TRUE((read.Y.array() == data.Y.array()).all());
    if (with_time) {
      EXPECT_TRUE((read.t.array() == data.t.array()).all());
    }
    EXPECT_TRUE(std::signbit(read.X(2, 2)));
    EXPECT_EQ(read.source, path);
    for (int i = 0; i < read.size(); ++i) EXPECT_EQ(read.line(i), i + 2);
  }
  EXPECT_EQ(dir.Entries(), (std::vector<std::string>{"with_t.csv", "without_t.csv"}));
}

TEST(CsvRoundTripTest, ShortestDigitsAreExactToo) {
  TempDir dir;
  const RobotData data = RandomRobotData(2, 25, false, 3);
  Eigen::MatrixXd values(data.size(), 8);
  values << data.X, data.Y;
  const std::string path = dir.File("shortest.csv");
  WriteCsvAtomically(path, RobotCsvHeader(2, false), values, 0);
  const RobotData read = ReadRobotCsv(path);
  EXPECT_TRUE((read.X.array() == data.X.array()).all());
  EXPECT_TRUE((read.Y.array() == data.Y.array()).all());
}

TEST(CsvRoundTripTest, CanonicalHeader) {
  EXPECT_EQ(RobotCsvHeader(2, true), (std::vector<std::string>{"t", "q1", "q2", "qd1", "qd2",
                                                               "qdd1", "qdd2", "tau1", "tau2"}));
  EXPECT_THROW(RobotCsvHeader(0, false), std::invalid_argument);
}

TEST(CsvRoundTripTest, NonFiniteValuesRoundTripWhenAllowed) {
  TempDir dir;
  RobotData data = RandomRobotData(1, 3, false, 5);
  data.X(0, 0) = std::numeric_limits<double>::quiet_NaN();
  data.X(1, 1) = std::numeric_limits<double>::infinity();
  data.Y(2, 0) = -std::numeric_limits<double>::infinity();
  const std::string path = dir.File("nonfinite.csv");
  WriteRobotCsv(path, data);
  CsvOptions options;
  options.allow_non_finite = true;
  const RobotData read = ReadRobotCsv(path, options);
  EXPECT_TRUE(std::isnan(read.X(0, 0)));
  EXPECT_EQ(read.X(1, 1), std::numeric_limits<double>::infinity());
  EXPECT_EQ(read.Y(2, 0), -std::numeric_limits<double>::infinity());
  ExpectError(ReadError(path), path, 2, 1, {"CSV column 1 (q1)", "'nan'", "finite"});
}

// ---- What the reader accepts ------------------------------------------------------------------

TEST(CsvReadTest, ShuffledAndExtraColumnsWhitespaceQuotesCrLfBomTrailingBlankLines) {
  TempDir dir;
  const std::string path = dir.File("shuffled.csv");
  WriteBytes(path,
             "\xEF\xBB\xBF"
             "tau2, note ,q2,\"qdd1\",t,q1,qd2,qd1,tau1,qdd2,speed\r\n"
             " 8 ,free text, 2,3 ,0.5,1,+5,4,7,6,fast\r\n"
             "18,,12,13,0.5,11,15,14,17,16e0,\r\n"
             "\r\n"
             "   \n");
  const RobotData data = ReadRobotCsv(path);
  ASSERT_EQ(data.num_joints, 2);
  ASSERT_EQ(data.size(), 2);
  ASSERT_TRUE(data.has_time());
  Eigen::MatrixXd expected_x(2, 6);
  expected_x << 1, 2, 4, 5, 3, 6, 11, 12, 14, 15, 13, 16;
  Eigen::MatrixXd expected_y(2, 2);
  expected_y << 7, 8, 17, 18;
  EXPECT_EQ(data.X, expected_x);
  EXPECT_EQ(data.Y, expected_y);
  EXPECT_EQ(data.t, Eigen::Vector2d(0.5, 0.5));  // Equal times are allowed.
  EXPECT_EQ(data.line, Eigen::Vector2i(2, 3));
}

TEST(CsvReadTest, NumberOfJointsInferredAndChecked) {
  TempDir dir;
  const std::string path = dir.File("three.csv");
  WriteBytes(path,
             "q1,q2,q3,qd1,qd2,qd3,qdd1,qdd2,qdd3,tau1,tau2,tau3\n"
             "1,2,3,4,5,6,7,8,9,10,11,12\n");
  CsvOptions options;
  options.expected_joints = 3;
  const RobotData data = ReadRobotCsv(path, options);
  EXPECT_EQ(data.num_joints, 3);
  EXPECT_FALSE(data.has_time());
  EXPECT_EQ(data.Y(0, 2), 12.0);
  options.expected_joints = 2;
  ExpectError(ReadError(path, options), path, 1, 0, {"expected 2 joints (model), file has 3"});
}

TEST(CsvReadTest, RowsGivesAContiguousSlice) {
  TempDir dir;
  RobotData data = RandomRobotData(2, 10, true, 9);
  const std::string path = dir.File("rows.csv");
  WriteRobotCsv(path, data);
  data = ReadRobotCsv(path);
  const RobotData part = data.Rows(3, 4);
  EXPECT_EQ(part.size(), 4);
  EXPECT_EQ(part.num_joints, 2);
  EXPECT_EQ(part.X, data.X.middleRows(3, 4));
  EXPECT_EQ(part.Y, data.Y.middleRows(3, 4));
  EXPECT_EQ(part.t, data.t.segment(3, 4));
  EXPECT_EQ(part.line, Eigen::Vector4i(5, 6, 7, 8));
  EXPECT_EQ(part.source, path);
  EXPECT_EQ(data.Rows(10, 0).size(), 0);
  EXPECT_THROW(data.Rows(8, 3), std::invalid_argument);
  EXPECT_THROW(data.Rows(-1, 2), std::invalid_argument);
  EXPECT_THROW(data.Rows(0, -1), std::invalid_argument);
}

TEST(CsvReadTest, GzipIsRecognisedByContentNotName) {
  TempDir dir;
  const std::string text =
      "t,q1,qd1,qdd1,tau1\n"
      "0,1,2,3,4\n"
      "0.1,5,6,7,8\n";
  WriteGzip(dir.File("data.csv.gz"), text);
  WriteGzip(dir.File("no_suffix.csv"), text);
  WriteBytes(dir.File("plain.csv.gz"), text);  // Misnamed: plain text.
  const RobotData reference = ReadRobotCsv(dir.File("plain.csv.gz"));
  for (const char* name : {"data.csv.gz", "no_suffix.csv"}) {
    const RobotData data = ReadRobotCsv(dir.File(name));
    EXPECT_EQ(data.X, reference.X) << name;
    EXPECT_EQ(data.Y, reference.Y) << name;
    EXPECT_EQ(data.t, reference.t) << name;
  }
}

TEST(CsvReadTest, InvalidOptionsAreCallerMistakes) {
  TempDir dir;
  const std::string path = dir.File("any.csv");
  WriteBytes(path, "q1,qd1,qdd1,tau1\n1,2,3,4\n");
  CsvOptions options;
  options.expected_joints = -1;
  EXPECT_THROW(ReadRobotCsv(path, options), std::invalid_argument);
  options = CsvOptions();
  options.max_abs = 0.0;
  EXPECT_THROW(ReadRobotCsv(path, options), std::invalid_argument);
  options.max_abs = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(ReadRobotCsv(path, options), std::invalid_argument);
  options.max_abs = std::numeric_limits<double>::infinity();
  EXPECT_NO_THROW(ReadRobotCsv(path, options));
}

// ---- Every error case, with its exact place -----------------------------------------------------

TEST_F(CsvErrorTest, MissingFileNamesThePathAndTheSystemReason) {
  const std::string missing = dir_.File("nowhere.csv");
  ExpectError(ReadError(missing), missing, 0, 0, {"cannot open", "No such file or directory"});
}

TEST_F(CsvErrorTest, DirectoryInsteadOfFile) {
  const std::string directory = dir_.path().string();
  ExpectError(ReadError(directory), directory, 0, 0, {"is a directory"});
}

TEST_F(CsvErrorTest, EmptyFile) {
  ExpectError(ErrorFor(""), path_, 0, 0, {"no data rows", "empty"});
}

TEST_F(CsvErrorTest, HeaderOnly) {
  ExpectError(ErrorFor("q1,qd1,qdd1,tau1\n"), path_, 1, 0, {"no data rows"});
  ExpectError(ErrorFor("q1,qd1,qdd1,tau1"), path_, 1, 0, {"no data rows"});
  ExpectError(ErrorFor("q1,qd1,qdd1,tau1\r\n\r\n  \n"), path_, 1, 0, {"no data rows"});
}

TEST_F(CsvErrorTest, EmptyFirstLine) {
  ExpectError(ErrorFor("\nq1,qd1,qdd1,tau1\n1,2,3,4\n"), path_, 1, 1,
              {"line 1 is empty", "header"});
}

TEST_F(CsvErrorTest, SemicolonOrTabSeparator) {
  ExpectError(ErrorFor("q1;qd1;qdd1;tau1\n1;2;3;4\n"), path_, 1, 3,
              {"single column", "';'", "','"});
  ExpectError(ErrorFor("q1\tqd1\tqdd1\ttau1\n1\t2\t3\t4\n"), path_, 1, 3,
              {"single column", "tab", "','"});
}

TEST_F(CsvErrorTest, OldMacLineEndings) {
  ExpectError(ErrorFor("q1,qd1,qdd1,tau1\r1,2,3,4\r"), path_, 1, 17, {"carriage return"});
}

TEST_F(CsvErrorTest, MissingHeaderRow) {
  ExpectError(ErrorFor("  0.5,2,3,4\n1,2,3,4\n"), path_, 1, 3,
              {"expected a header row", "'0.5'", "CSV column 1"});
}

TEST_F(CsvErrorTest, DuplicatedColumnNamesBothColumns) {
  ExpectError(ErrorFor("q1,qd1,qdd1,tau1, q1\n1,2,3,4,5\n"), path_, 1, 19,
              {"duplicated column 'q1'", "CSV columns 1 and 5"});
  ExpectError(ErrorFor("t,q1,qd1,qdd1,tau1,t\n0,1,2,3,4,0\n"), path_, 1, 20,
              {"duplicated column 't'", "CSV columns 1 and 6"});
}

TEST_F(CsvErrorTest, NoJointColumns) {
  ExpectError(ErrorFor("a,b,Q1\n1,2,3\n"), path_, 1, 0,
              {"no joint columns", "q1..qN", "'a', 'b', 'Q1'"});
}

TEST_F(CsvErrorTest, JointNumbersWithAGap) {
  ExpectError(ErrorFor("q1,q2,q4,qd1,qd2,qdd1,qdd2,tau1,tau2\n1,2,3,4,5,6,7,8,9\n"), path_, 1, 7,
              {"'q4'", "CSV column 3", "joint 4", "q3 is missing"});
}

TEST_F(CsvErrorTest, MissingColumnsAreListed) {
  ExpectError(ErrorFor("q1,q2,qd1,qd2,qdd1,tau1\n1,2,3,4,5,6\n"), path_, 1, 0,
              {"missing columns qdd2, tau2 (header has q1, q2, qd1, qd2, qdd1, tau1)"});
  ExpectError(ErrorFor("q1,qd1,qdd1\n1,2,3\n"), path_, 1, 0,
              {"missing column tau1 (header has q1, qd1, qdd1)"});
}

TEST_F(CsvErrorTest, RaggedRows) {
  // Too few: the column just after the end of the line, where the missing cell belongs.
  ExpectError(ErrorFor("q1,qd1,qdd1,tau1\n1,2,3,4\n1,2,3\n"), path_, 3, 6,
              {"expected 4 cells (as in the header), got 3"});
  // Too many: the first extra cell.
  ExpectError(ErrorFor("q1,qd1,qdd1,tau1\n1,2,3,4\n1,2,3,4,5\n"), path_, 3, 9,
              {"expected 4 cells (as in the header), got 5", "decimal mark"});
  ExpectError(ErrorFor("q1,qd1,qdd1,tau1\n1,5,2,3,4\n"), path_, 2, 9, {"got 5"});
}

TEST_F(CsvErrorTest, EmptyLineInsideTheData) {
  ExpectError(ErrorFor("q1,qd1,qdd1,tau1\n1,2,3,4\n\n  \n1,2,3,4\n"), path_, 3, 1,
              {"empty line inside the data"});
}

TEST_F(CsvErrorTest, NonNumericCellNamesLineColumnNameAndText) {
  ExpectError(ErrorFor("q1,q2,qd1,qd2,qdd1,qdd2,tau1,tau2\n"
                       "1,2,3,4,5,6,7,8\n"
                       "1,2,3,1.5abc,5,6,7,8\n"),
              path_, 3, 7, {"CSV column 4 (qd2)", "expected a number", "'1.5abc'"});
  ExpectError(ErrorFor("q1,qd1,qdd1,tau1\n1,2,  ,4\n"), path_, 2, 5,
              {"CSV column 3 (qdd1)", "empty cell"});
  ExpectError(ErrorFor("q1,qd1,qdd1,tau1\n1,2,3,1e\n"), path_, 2, 7, {"'1e'"});
  ExpectError(ErrorFor("q1,qd1,qdd1,tau1\n1,2,3,0x10\n"), path_, 2, 7, {"'0x10'"});
  ExpectError(ErrorFor("q1,qd1,qdd1,tau1\n1,2,3,1 2\n"), path_, 2, 7, {"'1 2'"});
}

TEST_F(CsvErrorTest, ColumnsCountCharactersNotBytes) {
  // "café," is five characters but six bytes: the bad cell starts at character 10.
  ExpectError(ErrorFor("note,q1,qd1,qdd1,tau1\ncafé,1,2,x,4\n"), path_, 2, 10,
              {"CSV column 4 (qdd1)", "'x'"});
}

TEST_F(CsvErrorTest, NonFiniteValues) {
  for (const char* text : {"nan", "NaN", "inf", "-Infinity"}) {
    SCOPED_TRACE(text);
    const std::string csv = std::string("q1,qd1,qdd1,tau1\n1,2,3,4\n1,") + text + ",3,4\n";
    ExpectError(ErrorFor(csv), path_, 3, 3,
                {"CSV column 2 (qd1)", "expected a finite number", text, "allow_non_finite"});
    CsvOptions options;
    options.allow_non_finite = true;
    EXPECT_FALSE(std::isfinite(ReadRobotCsv(path_, options).X(1, 1)));
  }
}

TEST_F(CsvErrorTest, AbsurdMagnitudes) {
  ExpectError(ErrorFor("q1,qd1,qdd1,tau1\n1,2,3,-2.5e7\n"), path_, 2, 7,
              {"CSV column 4 (tau1)", "at most 1e+06", "'-2.5e7'", "units"});
  CsvOptions options;
  options.max_abs = 1e8;
  EXPECT_EQ(ReadRobotCsv(path_, options).Y(0, 0), -2.5e7);
  options.max_abs = 10.0;
  ExpectError(ErrorFor("q1,qd1,qdd1,tau1\n1,2,3,4\n1,2,30,4\n", options), path_, 3, 5,
              {"CSV column 3 (qdd1)", "at most 10"});
  // Beyond the range of a double.
  ExpectError(ErrorFor("q1,qd1,qdd1,tau1\n1e999,2,3,4\n"), path_, 2, 1,
              {"CSV column 1 (q1)", "'1e999'", "range of a double"});
}

TEST_F(CsvErrorTest, TimeMustBeFinite) {
  CsvOptions options;
  options.allow_non_finite = true;
  ExpectError(ErrorFor("q1,qd1,qdd1,tau1,t\n1,2,3,4,nan\n", options), path_, 2, 9,
              {"CSV column 5 (t)", "finite time", "'nan'"});
  // Large time stamps are fine (max_abs does not apply to t).
  WriteBytes(path_, "t,q1,qd1,qdd1,tau1\n1700000000.25,1,2,3,4\n");
  EXPECT_EQ(ReadRobotCsv(path_).t(0), 1700000000.25);
}

TEST_F(CsvErrorTest, TimeThatStartsAgainMakesTrajectories) {
  // Three trajectories, each with its time from 0 (equal times stay in one trajectory).
  WriteBytes(path_,
             "q1,qd1,qdd1,tau1,t\n1,2,3,4,0\n1,2,3,4,1\n1,2,3,4,1\n1,2,3,4,0\n1,2,3,4,0.5\n"
             "1,2,3,4,0.25\n");
  const RobotData data = ReadRobotCsv(path_);
  EXPECT_EQ(data.size(), 6);
  EXPECT_EQ(data.segments(), (std::vector<int>{0, 3, 5}));
  EXPECT_EQ(data.Rows(3, 3).segments(), (std::vector<int>{0, 2}));
  // Without times the log is one trajectory.
  WriteBytes(path_, "q1,qd1,qdd1,tau1\n1,2,3,4\n1,2,3,4\n");
  EXPECT_EQ(ReadRobotCsv(path_).segments(), (std::vector<int>{0}));
}

TEST_F(CsvErrorTest, MotorCurrentsInPlaceOfTorques) {
  WriteBytes(path_, "q1,q2,qd1,qd2,qdd1,qdd2,cur2,cur1\n1,2,3,4,5,6,8,7\n");
  const RobotData data = ReadRobotCsv(path_);
  EXPECT_EQ(data.target, RobotData::Target::kCurrent);
  EXPECT_EQ(std::string(data.target_prefix()), "cur");
  EXPECT_EQ(data.Y(0, 0), 7.0);
  EXPECT_EQ(data.Y(0, 1), 8.0);
  // Written back with cur columns, read back the same.
  const std::string copy = dir_.File("copy.csv");
  WriteRobotCsv(copy, data);
  const RobotData again = ReadRobotCsv(copy);
  EXPECT_EQ(again.target, RobotData::Target::kCurrent);
  EXPECT_EQ(again.Y, data.Y);
  // Torques win when both are there; cur columns are then ignored.
  WriteBytes(path_, "q1,qd1,qdd1,tau1,cur1\n1,2,3,4,9\n");
  const RobotData both = ReadRobotCsv(path_);
  EXPECT_EQ(both.target, RobotData::Target::kTorque);
  EXPECT_EQ(both.Y(0, 0), 4.0);
  // Neither: the message says both names.
  ExpectError(ErrorFor("q1,qd1,qdd1\n1,2,3\n"), path_, 1, 0,
              {"missing column tau1", "cur1..curN instead of tau1..tauN"});
  // Some currents only: the missing ones are named as currents would not help; torques asked.
  ExpectError(ErrorFor("q1,q2,qd1,qd2,qdd1,qdd2,cur1\n1,2,3,4,5,6,7\n"), path_, 1, 0,
              {"missing columns tau1, tau2"});
}

TEST_F(CsvErrorTest, BinaryFile) {
  ExpectError(ErrorFor(std::string("q1,qd1,qdd1,tau1\n1,2\0,3,4\n", 26)), path_, 2, 4,
              {"NUL byte", "binary"});
}

TEST_F(CsvErrorTest, CorruptOrTruncatedGzip) {
  std::string text = "q1,qd1,qdd1,tau1\n";
  std::mt19937 generator(1);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  for (int i = 0; i < 2000; ++i) {
    for (int j = 0; j < 4; ++j) text += (j > 0 ? "," : "") + std::to_string(uniform(generator));
    text += "\n";
  }
  const std::string gz = dir_.File("whole.csv.gz");
  WriteGzip(gz, text);
  ASSERT_EQ(ReadRobotCsv(gz).size(), 2000);
  const std::string bytes = ReadBytes(gz);

  const std::string truncated = dir_.File("truncated.csv.gz");
  WriteBytes(truncated, bytes.substr(0, bytes.size() / 2));
  const DataError cut = ReadError(truncated);
  EXPECT_EQ(cut.file(), truncated);
  // zlib hands out data in chunks, so the line is where reading stopped, at or before the end
  // of the readable data.
  EXPECT_GE(cut.line(), 1);
  EXPECT_LE(cut.line(), 2001);
  EXPECT_EQ(cut.column(), 0);
  EXPECT_NE(cut.message().find("truncated"), std::string::npos) << cut.what();

  std::string damaged = bytes;
  for (std::size_t i = damaged.size() / 3; i < damaged.size() / 3 + 64; ++i) damaged[i] ^= 0x5A;
  const std::string corrupt = dir_.File("corrupt.csv.gz");
  WriteBytes(corrupt, damaged);
  try {
    ReadRobotCsv(corrupt);
    ADD_FAILURE() << "corrupt gzip data read without error";
  } catch (const DataError& error) {
    EXPECT_EQ(error.file(), corrupt);
    EXPECT_GE(error.line(), 1);
    // Damage inside a block shows as corrupt data; damage that yields other bytes is then
    // caught by the CRC check or by the CSV checks.
    EXPECT_TRUE(error.message().find("corrupt gzip data") != std::string::npos ||
                error.message().find("CSV column") != std::string::npos ||
                error.message().find("cells") != std::string::npos)
        << error.what();
  }
}

// ---- Atomic writing ----------------------------------------------------------------------------

TEST(AtomicWriteTest, CreatesAndReplacesLeavingNoTemporaryFile) {
  TempDir dir;
  const std::string path = dir.File("out.json");
  WriteTextAtomically(path, "{\"a\": 1}\n");
  EXPECT_EQ(ReadBytes(path), "{\"a\": 1}\n");
  fs::permissions(path, fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read);
  WriteTextAtomically(path, "{}\n");
  EXPECT_EQ(ReadBytes(path), "{}\n");
  EXPECT_EQ(fs::status(path).permissions() & fs::perms::all,
            fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read);
  WriteTextAtomically(path, "");
  EXPECT_EQ(ReadBytes(path), "");
  EXPECT_EQ(dir.Entries(), std::vector<std::string>{"out.json"});
}

TEST(AtomicWriteTest, FollowsSymbolicLinks) {
  TempDir dir;
  const std::string target = dir.File("target.html");
  const std::string link = dir.File("link.html");
  WriteBytes(target, "old");
  fs::create_symlink(target, link);
  WriteTextAtomically(link, "new");
  EXPECT_TRUE(fs::is_symlink(link));
  EXPECT_EQ(ReadBytes(target), "new");
}

TEST(AtomicWriteTest, PathThatIsADirectory) {
  TempDir dir;
  fs::create_directory(dir.path() / "sub");
  WriteBytes(dir.File("sub/keep.txt"), "keep");
  const std::string path = dir.File("sub");
  try {
    WriteTextAtomically(path, "text");
    ADD_FAILURE() << "writing over a directory did not throw";
  } catch (const DataError& error) {
    ExpectError(error, path, 0, 0, {"cannot write", "is a directory"});
  }
  EXPECT_EQ(ReadBytes(dir.File("sub/keep.txt")), "keep");
  EXPECT_EQ(dir.Entries(), std::vector<std::string>{"sub"});
  EXPECT_THROW(WriteTextAtomically("", "text"), std::invalid_argument);
}

TEST(AtomicWriteTest, MissingDirectory) {
  TempDir dir;
  const std::string path = dir.File("absent/out.csv");
  try {
    WriteTextAtomically(path, "text");
    ADD_FAILURE() << "writing into a missing directory did not throw";
  } catch (const DataError& error) {
    ExpectError(error, path, 0, 0, {"cannot write", "temporary file", "No such file"});
  }
  EXPECT_TRUE(dir.Entries().empty());
}

TEST(AtomicWriteTest, FailureHalfWayLeavesTheOldFileUntouched) {
  // A file size limit makes write() fail after part of the data is on disk (EFBIG), as a full
  // disk would; it applies to every user, root included.
  TempDir dir;
  const std::string path = dir.File("results.csv");
  const std::string old_bytes = "q1,qd1,qdd1,tau1\n1,2,3,4\n";
  WriteBytes(path, old_bytes);

  const RobotData big = RandomRobotData(7, 5000, true, 21);  // About 3 MB of text.
  struct rlimit saved;
  ASSERT_EQ(getrlimit(RLIMIT_FSIZE, &saved), 0);
  struct rlimit limited = saved;
  limited.rlim_cur = 64 * 1024;
  void (*saved_handler)(int) = signal(SIGXFSZ, SIG_IGN);
  ASSERT_EQ(setrlimit(RLIMIT_FSIZE, &limited), 0);
  bool threw = false;
  std::string what;
  try {
    WriteRobotCsv(path, big);
  } catch (const DataError& error) {
    threw = true;
    what = error.what();
  }
  setrlimit(RLIMIT_FSIZE, &saved);
  signal(SIGXFSZ, saved_handler);

  ASSERT_TRUE(threw) << "the size-limited write did not fail";
  EXPECT_EQ(what.rfind(path + ": cannot write: writing the temporary file failed: ", 0), 0u)
      << what;
  EXPECT_EQ(ReadBytes(path), old_bytes);
  EXPECT_EQ(dir.Entries(), std::vector<std::string>{"results.csv"});
  // And the same write succeeds without the limit.
  WriteRobotCsv(path, big);
  EXPECT_EQ(ReadRobotCsv(path).size(), 5000);
}

TEST(AtomicWriteTest, ReadOnlyDirectoryLeavesTheOldFileUntouched) {
  if (geteuid() == 0) GTEST_SKIP() << "root writes into read-only directories";
  TempDir dir;
  const std::string path = dir.File("model.json");
  WriteBytes(path, "old");
  fs::permissions(dir.path(), fs::perms::owner_read | fs::perms::owner_exec);
  try {
    WriteTextAtomically(path, "new");
    ADD_FAILURE() << "writing into a read-only directory did not throw";
  } catch (const DataError& error) {
    ExpectError(error, path, 0, 0, {"cannot write", "Permission denied"});
  }
  fs::permissions(dir.path(), fs::perms::owner_all);
  EXPECT_EQ(ReadBytes(path), "old");
  EXPECT_EQ(dir.Entries(), std::vector<std::string>{"model.json"});
}

TEST(AtomicWriteTest, CallerMistakesLeaveTheOldFileUntouched) {
  TempDir dir;
  const std::string path = dir.File("values.csv");
  WriteBytes(path, "old");
  const Eigen::MatrixXd values = Eigen::MatrixXd::Ones(2, 3);
  EXPECT_THROW(WriteCsvAtomically(path, {"a", "b"}, values), std::invalid_argument);
  EXPECT_THROW(WriteCsvAtomically(path, {"a", "b,c", "d"}, values), std::invalid_argument);
  EXPECT_THROW(WriteCsvAtomically(path, {"a", "b", "c"}, values, 18), std::invalid_argument);
  RobotData data = RandomRobotData(2, 4, true, 1);
  data.Y.resize(4, 3);
  EXPECT_THROW(WriteRobotCsv(path, data), std::invalid_argument);
  data = RandomRobotData(2, 4, true, 1);
  data.t.resize(3);
  EXPECT_THROW(WriteRobotCsv(path, data), std::invalid_argument);
  EXPECT_EQ(ReadBytes(path), "old");
  EXPECT_EQ(dir.Entries(), std::vector<std::string>{"values.csv"});
}

TEST(AtomicWriteTest, CsvText) {
  TempDir dir;
  const std::string path = dir.File("small.csv");
  Eigen::MatrixXd values(2, 2);
  values << 0.1, -2, 1e-20, 3.25;
  WriteCsvAtomically(path, {"x", "y"}, values, 3);
  EXPECT_EQ(ReadBytes(path), "x,y\n0.1,-2\n1e-20,3.25\n");
}

// ---- The real data sets ------------------------------------------------------------------------

class RealDataTest : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!fs::is_directory(kDataDir)) GTEST_SKIP() << "no real data in " << kDataDir;
  }
  const std::string kDataDir = STRUCTGP_REAL_DATA_DIR;
};

TEST_F(RealDataTest, Sarcos) {
  const RobotData data = ReadRobotCsv(kDataDir + "/sarcos/sarcos_inv_test.csv.gz");
  EXPECT_EQ(data.num_joints, 7);
  EXPECT_EQ(data.size(), 4449);
  EXPECT_EQ(data.X.cols(), 21);
  EXPECT_EQ(data.Y.cols(), 7);
  EXPECT_FALSE(data.has_time());
  EXPECT_EQ(data.X(0, 0), 0.019478);
  EXPECT_EQ(data.Y(0, 0), 50.292652);
  EXPECT_EQ(data.line(4448), 4450);
}

TEST_F(RealDataTest, Ur10PickAndPlace) {
  CsvOptions options;
  options.expected_joints = 6;
  const RobotData train = ReadRobotCsv(kDataDir + "/ur10-picknplace/train.csv.gz", options);
  const RobotData test = ReadRobotCsv(kDataDir + "/ur10-picknplace/test.csv.gz", options);
  EXPECT_EQ(train.num_joints, 6);
  EXPECT_EQ(train.size(), 9879);
  EXPECT_EQ(test.size(), 2470);
  ASSERT_TRUE(train.has_time());
  ASSERT_TRUE(test.has_time());
  EXPECT_EQ(train.t(0), 0.0);
  EXPECT_EQ(train.t(1), 0.008);
  EXPECT_EQ(test.t(0), 79.032);  // The test file carries on from the train file.
  EXPECT_EQ(train.X(0, 0), 0.0202);
  EXPECT_EQ(test.X(0, 17), 3.855421687);  // qdd6.
  EXPECT_EQ(test.Y(0, 0), -30.809);
}

}  // namespace
}  // namespace structgp
