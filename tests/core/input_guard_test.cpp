// The input guards of core/: the decimal grammar, the checked integer, the UTF-8 and nesting
// checks, the JSON entry and the regular-file rule (docs/input-ranges.md). Each reproducer of
// issue 11 is here byte for byte, and each expected value is independent of the code: a
// literal, an exact identity, or a slow reference written in the test.
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <gtest/gtest.h>
#include <cfloat>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <random>
#include <string>

#include "core/decimal.hpp"
#include "core/input_file.hpp"
#include "core/input_ranges.hpp"
#include "core/json_input.hpp"
#include "core/text_guard.hpp"
#include "tests/common/char_device.hpp"
#include "tests/common/seed.hpp"

namespace ncd {
namespace {

namespace fs = std::filesystem;

std::string message_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no InputError)";
}

// ------------------------------------------------------------------------- decimal grammar

TEST(Decimal, ReadsTheGrammarAndNothingElse) {
  struct Case {
    const char* text;
    double value;
  };
  for (const Case& c : std::vector<Case>{{"0", 0.0},
                                         {"-0", 0.0},
                                         {"+3e1", 30.0},
                                         {"-12.5", -12.5},
                                         {"1.5e-3", 0.0015},
                                         {"5.", 5.0},
                                         {".5", 0.5},
                                         {"007", 7.0},
                                         {"1E+2", 100.0},
                                         {"2.2250738585072014e-308", DBL_MIN},
                                         {"1.7976931348623157e308", DBL_MAX}}) {
    const DecimalResult r = parse_decimal(c.text);
    ASSERT_TRUE(r) << c.text;
    EXPECT_EQ(r.value, c.value) << c.text;
    EXPECT_FALSE(std::signbit(r.value) && r.value == 0.0) << c.text;  // -0 reads 0
  }
  for (const char* bad :
       {"",    "+",   "-",    ".",    "+-10",     "-+10",  "--1", "0x1p5", "0X10",
        "1p5", "inf", "-inf", "nan",  "infinity", "1e",    "1e+", "e5",    "1.5mm",
        " 1",  "1 ",  "1,5",  "1..5", "1.5.",     "1e5.5", "١"}) {
    const DecimalResult r = parse_decimal(bad);
    EXPECT_EQ(r.error, DecimalError::Malformed) << "'" << bad << "' read as " << r.value;
  }
}

TEST(Decimal, SubnormalAndUnderflowAreTooSmallOverflowIsTooLarge) {
  for (const char* small : {"1e-310", "-1e-310", "4.9e-324", "2e-324", "1e-400", "0.0001e-305"}) {
    EXPECT_EQ(parse_decimal(small).error, DecimalError::TooSmall) << small;
  }
  for (const char* large : {"1e400", "-1e309", "1000e306", "0.001e312"}) {
    EXPECT_EQ(parse_decimal(large).error, DecimalError::TooLarge) << large;
  }
  EXPECT_TRUE(parse_decimal("0e999999"));  // zero is zero whatever its exponent
  EXPECT_TRUE(parse_decimal("1e-300"));    // small but normal: a number (ranges decide later)
  const std::string why = message_of([] { (void)decimal_or_throw("1e-310", "pts.txt:3"); });
  EXPECT_NE(why.find("pts.txt:3: '1e-310' is too small"), std::string::npos) << why;
  EXPECT_EQ(why.find("finite"), std::string::npos) << why;  // the reason of issue 11, corrected
}

// Random decimal texts against strtod (the C library's correctly rounded reader) as the
// reference, on the grammar's accepted forms; prints its seed.
TEST(Decimal, AgreesWithStrtodOnRandomDecimals) {
  const std::uint64_t seed = test::seed();
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<int> digit(0, 9), len(1, 12), expo(-300, 300), coin(0, 1);
  for (int n = 0; n < 20000; ++n) {
    std::string t = coin(rng) ? "-" : "";
    for (int i = len(rng); i > 0; --i) t += static_cast<char>('0' + digit(rng));
    if (coin(rng)) {
      t += ".";
      for (int i = len(rng); i > 0; --i) t += static_cast<char>('0' + digit(rng));
    }
    if (coin(rng)) t += "e" + std::to_string(expo(rng));
    const double want = std::strtod(t.c_str(), nullptr);
    const DecimalResult r = parse_decimal(t);
    if (std::isinf(want)) {
      ASSERT_EQ(r.error, DecimalError::TooLarge) << t << " seed " << seed;
    } else if (want != 0.0 && std::abs(want) < DBL_MIN) {
      ASSERT_EQ(r.error, DecimalError::TooSmall) << t << " seed " << seed;
    } else {
      ASSERT_TRUE(r) << t << " seed " << seed;
      ASSERT_EQ(r.value, want == 0.0 ? 0.0 : want) << t << " seed " << seed;
    }
  }
}

// ------------------------------------------------------------------------- integers

TEST(CheckedInteger, WholeNumbersInRangeOnly) {
  EXPECT_EQ(checked_integer(300.0, 1, 1000, "n"), 300);
  EXPECT_EQ(checked_integer(-5.0, -5, 5, "n"), -5);
  const std::string frac = message_of([] { (void)checked_integer(4.9, 4, 100000, "\"k\""); });
  EXPECT_NE(frac.find("\"k\" = 4.9 is not a whole number"), std::string::npos) << frac;
  EXPECT_NE(frac.find("from 4 to 100000"), std::string::npos) << frac;
  const std::string big = message_of([] { (void)checked_integer(3e9, 4, 100000, "\"k\""); });
  EXPECT_NE(big.find("\"k\" = 3000000000 is out of range"), std::string::npos) << big;
  for (double bad : {std::nan(""), HUGE_VAL, -HUGE_VAL, 1e300, -1e300, 0.5}) {
    EXPECT_NE(message_of([&] { (void)checked_integer(bad, 0, 10, "n"); }), "(no InputError)");
  }
}

TEST(JsonInteger, EveryJsonNumberKind) {
  using nlohmann::json;
  EXPECT_EQ(json_integer(json(7), 1, 10, "n"), 7);
  EXPECT_EQ(json_integer(json(7u), 1, 10, "n"), 7);
  EXPECT_EQ(json_integer(json(7.0), 1, 10, "n"), 7);
  EXPECT_EQ(json_integer(json::parse("3e2"), 1, 1000, "n"), 300);
  for (const char* bad : {"3e9", "4.9", "18446744073709551615", "-1", "\"5\"", "true", "null"}) {
    EXPECT_NE(message_of([&] { (void)json_integer(json::parse(bad), 0, 1000000, "n"); }),
              "(no InputError)")
        << bad;
  }
}

TEST(CheckedRange, NamesValueRangeUnitAndWayOut) {
  const std::string m = message_of([] {
    (void)checked_range(1e12, ranges::kMaxFeedMmPerMin.lo, ranges::kMaxFeedMmPerMin.hi,
                        "m.toml: max_feed_mm_per_min", ranges::kMaxFeedMmPerMin.unit,
                        "give a value in the range");
  });
  for (const char* part : {"max_feed_mm_per_min = 1000000000000", "[1, 120000] mm/min",
                           "give a value in the range", "docs/input-ranges.md"}) {
    EXPECT_NE(m.find(part), std::string::npos) << part << "\n" << m;
  }
}

// ------------------------------------------------------------------------- text checks

TEST(Utf8, ValidTextPassesEveryMalformedFormIsFound) {
  bool nul = false;
  EXPECT_EQ(find_bad_utf8("plain ascii\n", nul), std::string_view::npos);
  EXPECT_EQ(find_bad_utf8("µm, ±, ≤, 🙂", nul), std::string_view::npos);
  struct Case {
    std::string text;
    std::size_t at;
  };
  for (const Case& c :
       std::vector<Case>{{"device = '\xFF'", 10},     // issue 11, byte for byte
                         {"'\xBE", 1},                // a continuation byte without a lead
                         {"ab\xC0\x80", 2},           // overlong NUL
                         {"\xE0\x80\xAF", 0},         // overlong '/'
                         {"\xED\xA0\x80", 0},         // a surrogate, U+D800
                         {"\xF4\x90\x80\x80", 0},     // U+110000, above the last code point
                         {"x\xE2\x82", 1},            // truncated at the end
                         {"\xC3(", 0},                // a lead byte without its continuation
                         {"\xF5\x80\x80\x80", 0}}) {  // a lead byte that never occurs
    EXPECT_EQ(find_bad_utf8(c.text, nul), c.at) << c.text;
    EXPECT_FALSE(nul);
  }
  EXPECT_EQ(find_bad_utf8(std::string("a = 1\0", 6), nul), 5u);
  EXPECT_TRUE(nul);
  const std::string m = message_of([] {
    require_utf8_text("period_s = 1\n[link]\ndevice = '\xFF'\n", "m.toml", "machine file");
  });
  EXPECT_NE(m.find("m.toml: line 3, column 11 (byte offset 30)"), std::string::npos) << m;
  EXPECT_NE(m.find("0xFF is not valid UTF-8"), std::string::npos) << m;
}

// Every 1-, 2-, 3- and 4-byte sequence that starts with each lead byte, against a slow
// reference: decode by the definition (RFC 3629) and check the code point.
TEST(Utf8, AgreesWithADecoderByDefinition) {
  const auto reference_ok = [](const std::string& s) {
    std::size_t i = 0;
    while (i < s.size()) {
      const auto b = static_cast<unsigned char>(s[i]);
      int len = b < 0x80 ? 1 : (b >> 5) == 6 ? 2 : (b >> 4) == 14 ? 3 : (b >> 3) == 30 ? 4 : 0;
      if (len == 0 || i + static_cast<std::size_t>(len) > s.size()) return false;
      std::uint32_t cp = len == 1 ? b : b & (0xFFu >> (len + 1));
      for (int k = 1; k < len; ++k) {
        const auto c = static_cast<unsigned char>(s[i + static_cast<std::size_t>(k)]);
        if ((c >> 6) != 2) return false;
        cp = (cp << 6) | (c & 0x3Fu);
      }
      const std::uint32_t min[] = {0, 0, 0x80, 0x800, 0x10000};
      if (cp < min[len] || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF) || cp == 0) {
        return false;
      }
      i += static_cast<std::size_t>(len);
    }
    return true;
  };
  bool nul = false;
  for (int lead = 1; lead < 256; ++lead) {
    for (int second = 0; second < 256; second += 3) {
      for (int third : {0x80, 0x9F, 0xA0, 0xBF, 0x41}) {
        for (int fourth : {0x80, 0xBF, 0x30}) {
          for (std::size_t n = 1; n <= 4; ++n) {
            const char bytes[4] = {static_cast<char>(lead), static_cast<char>(second),
                                   static_cast<char>(third), static_cast<char>(fourth)};
            const std::string s(bytes, n);
            if (s.find('\0') != std::string::npos) continue;
            ASSERT_EQ(find_bad_utf8(s, nul) == std::string_view::npos, reference_ok(s))
                << std::hex << lead << " " << second << " " << third << " " << fourth << " n " << n;
          }
        }
      }
    }
  }
}

TEST(TomlDepth, DeepNestingAndLongDottedKeysAreFoundStringsAndCommentsAreNot) {
  const std::string deep_array = "a = " + std::string(100000, '[');
  EXPECT_EQ(find_toml_too_deep(deep_array, kMaxNestingDepth), 4u + kMaxNestingDepth);
  std::string deep_table = "a = ";
  for (int i = 0; i < 100000; ++i) deep_table += "{b=";
  EXPECT_EQ(find_toml_too_deep(deep_table, kMaxNestingDepth), 4u + 3u * kMaxNestingDepth);
  std::string dotted = "a";
  for (int i = 0; i < 100; ++i) dotted += ".a";
  EXPECT_EQ(find_toml_too_deep(dotted + " = 1\n", kMaxNestingDepth),
            1u + 2u * (kMaxNestingDepth - 1));
  // 64 levels pass; brackets in strings, multi-line strings and comments do not count.
  EXPECT_EQ(find_toml_too_deep("a = " + std::string(64, '[') + std::string(64, ']'), 64),
            std::string_view::npos);
  const std::string quiet = "s = '" + std::string(200, '[') + "'\n" + "t = \"\\\"" +
                            std::string(200, '{') + "\"\n" + "u = '''\n" + std::string(200, '[') +
                            "\n'''\n" + "v = \"\"\"" + std::string(200, '[') + "\"\"\"\n" + "# " +
                            std::string(200, '[') + "\nx = [1.5, 2.5, 3.5, 4.5]\n";
  EXPECT_EQ(find_toml_too_deep(quiet, kMaxNestingDepth), std::string_view::npos);
  const std::string m = message_of([&] { require_toml_depth(deep_array, "m.toml"); });
  EXPECT_NE(m.find("m.toml: line 1, column 69 (byte offset 68)"), std::string::npos) << m;
  EXPECT_NE(m.find("deeper than 64"), std::string::npos) << m;
}

// ------------------------------------------------------------------------- JSON entry

TEST(JsonInput, DeepNestingIsRefusedBeforeParsing) {
  const std::string deep = R"({"polyline":{"points":)" + std::string(100000, '[');
  const std::string m = message_of([&] { (void)parse_json_input(deep, "p.json"); });
  EXPECT_NE(m.find("p.json: line 1, column 85 (byte offset 84)"), std::string::npos) << m;
  EXPECT_NE(m.find("nesting deeper than 64"), std::string::npos) << m;
  // Brackets inside strings do not count; 64 levels parse.
  EXPECT_NO_THROW((void)parse_json_input("{\"k\":\"" + std::string(1000, '[') + "\"}", "s"));
  EXPECT_NO_THROW((void)parse_json_input(std::string(64, '[') + std::string(64, ']'), "s"));
}

TEST(JsonInput, AnUnrepresentableNumberNamesItsKey) {
  const std::string top = message_of([] { (void)parse_json_input(R"({"nurbs":1e400})", "p"); });
  EXPECT_NE(top.find("p: \"nurbs\" is out of range"), std::string::npos) << top;
  const std::string inner =
      message_of([] { (void)parse_json_input(R"({"a":{"b":[1,2,-1e999]},"c":0})", "p"); });
  EXPECT_NE(inner.find("\"a.b[2]\" is out of range"), std::string::npos) << inner;
  const std::string utf = message_of([] { (void)parse_json_input("{\"cmd\":\"\xFF\"}", "r"); });
  EXPECT_NE(utf.find("r: not valid JSON"), std::string::npos) << utf;
}

// ------------------------------------------------------------------------- regular files

class InputFile : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("ncd_input_file_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(InputFile, ReadsARegularFileAndRefusesEverythingElseWithoutBlocking) {
  const fs::path file = dir_ / "m.toml";
  {
    std::FILE* f = std::fopen(file.c_str(), "wb");
    std::fputs("a = 1\n", f);
    std::fclose(f);
  }
  EXPECT_EQ(read_input_file(file, "--machine"), "a = 1\n");
  const fs::path link = dir_ / "link.toml";
  fs::create_symlink(file, link);
  EXPECT_EQ(read_input_file(link, "--machine"), "a = 1\n");  // a link to a file is the file

  const fs::path fifo = dir_ / "fifo";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  // A FIFO without a writer would block an open() without O_NONBLOCK forever: the test would
  // hang until ctest's timeout instead of passing.
  for (const auto& [path, kind] : std::vector<std::pair<std::string, std::string>>{
           {dir_.string(), "is a directory"},
           {fifo.string(), "is a FIFO (named pipe)"},
           {test::character_device(), "is a character device"}}) {
    // (clang 14 cannot capture a structured binding: the lambdas take it by an init-capture.)
    const std::string m = message_of([&p = path] { (void)read_input_file(p, "--machine"); });
    EXPECT_NE(m.find(path + " (--machine) " + kind + ", not a regular file"), std::string::npos)
        << m;
    const std::string r = message_of([&p = path] { require_regular_file(p, "NC program"); });
    EXPECT_NE(r.find(path + " (NC program) " + kind), std::string::npos) << r;
  }
  const std::string missing = (dir_ / "missing").string();
  const std::string m = message_of([&] { (void)read_input_file(missing, "--machine"); });
  EXPECT_NE(m.find("cannot open " + missing + " (--machine): No such file"), std::string::npos)
      << m;
  EXPECT_NE(message_of([&] { (void)read_input_file(file, "x", 3); }).find("larger than 3 bytes"),
            std::string::npos);
}

}  // namespace
}  // namespace ncd
