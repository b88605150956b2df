// Tests of the dependency-free SVG chart writer (apps/mvkp/svg_plot.h).
#include "svg_plot.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <regex>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace mvkp::cli {
namespace {

const double kNaN = std::numeric_limits<double>::quiet_NaN();
const double kInf = std::numeric_limits<double>::infinity();

size_t Count(const std::string& s, const std::string& what) {
  size_t n = 0;
  for (size_t p = s.find(what); p != std::string::npos; p = s.find(what, p + what.size())) ++n;
  return n;
}

// Minimal XML well-formedness check: one root, tags nest and match, quoted
// attributes, no raw '<' in text or attributes, '&' only in known entities.
::testing::AssertionResult WellFormed(const std::string& svg) {
  if (svg.rfind("<svg", 0) != 0) return ::testing::AssertionFailure() << "does not start with <svg";
  std::string trimmed = svg;
  while (!trimmed.empty() && std::isspace(static_cast<unsigned char>(trimmed.back()))) trimmed.pop_back();
  if (trimmed.size() < 6 || trimmed.compare(trimmed.size() - 6, 6, "</svg>") != 0)
    return ::testing::AssertionFailure() << "does not end with </svg>";
  if (Count(svg, "<g ") + Count(svg, "<g>") != Count(svg, "</g>"))
    return ::testing::AssertionFailure() << "unbalanced <g>";
  static const std::regex entity("^&(amp|lt|gt|quot|apos|#[0-9]+|#x[0-9a-fA-F]+);");
  std::vector<std::string> stack;
  bool closed_root = false;
  for (size_t i = 0; i < svg.size();) {
    char ch = svg[i];
    if (ch == '&') {
      if (!std::regex_search(svg.substr(i, 12), entity))
        return ::testing::AssertionFailure() << "raw & at " << i << ": " << svg.substr(i, 20);
      ++i;
    } else if (ch == '<') {
      if (closed_root) return ::testing::AssertionFailure() << "content after the root element";
      bool closing = i + 1 < svg.size() && svg[i + 1] == '/';
      size_t p = i + (closing ? 2 : 1), q = p;
      while (q < svg.size() && (std::isalnum(static_cast<unsigned char>(svg[q])) || svg[q] == '-')) ++q;
      std::string name = svg.substr(p, q - p);
      if (name.empty()) return ::testing::AssertionFailure() << "bad tag at " << i << ": " << svg.substr(i, 20);
      // Scan attributes up to '>' honouring quotes.
      char quote = 0;
      for (; q < svg.size(); ++q) {
        char c = svg[q];
        if (quote) {
          if (c == quote) quote = 0;
          else if (c == '<') return ::testing::AssertionFailure() << "raw < in attribute of " << name;
          else if (c == '&' && !std::regex_search(svg.substr(q, 12), entity))
            return ::testing::AssertionFailure() << "raw & in attribute of " << name;
        } else if (c == '"' || c == '\'') {
          quote = c;
        } else if (c == '>' || c == '<') {
          break;
        }
      }
      if (q >= svg.size() || svg[q] != '>') return ::testing::AssertionFailure() << "unterminated <" << name;
      bool self_closing = svg[q - 1] == '/';
      if (closing) {
        if (stack.empty() || stack.back() != name)
          return ::testing::AssertionFailure() << "</" << name << "> does not match <"
                                               << (stack.empty() ? "" : stack.back()) << ">";
        stack.pop_back();
        if (stack.empty()) closed_root = true;
      } else if (!self_closing) {
        stack.push_back(name);
      }
      i = q + 1;
    } else {
      if (closed_root && !std::isspace(static_cast<unsigned char>(ch)))
        return ::testing::AssertionFailure() << "text after the root element";
      ++i;
    }
  }
  if (!stack.empty()) return ::testing::AssertionFailure() << "<" << stack.back() << "> not closed";
  return ::testing::AssertionSuccess();
}

std::vector<std::string> Labels(const std::string& svg, const std::string& cls) {
  std::regex re("class=\"" + cls + "\">([^<]*)<");
  std::vector<std::string> out;
  for (auto it = std::sregex_iterator(svg.begin(), svg.end(), re); it != std::sregex_iterator(); ++it)
    out.push_back((*it)[1]);
  return out;
}

TEST(SvgPlot, NiceTicks) {
  auto t = NiceTicks(0, 1, 5);
  ASSERT_EQ(t.size(), 6u);
  for (size_t i = 0; i < t.size(); ++i) EXPECT_NEAR(t[i], 0.2 * i, 1e-12);
  EXPECT_EQ(NiceTicks(0, 10, 4), (std::vector<double>{0, 2.5, 5, 7.5, 10}));
  EXPECT_EQ(NiceTicks(-3, 17, 4), (std::vector<double>{0, 5, 10, 15}));
  EXPECT_EQ(NiceTicks(0, 100, 5), (std::vector<double>{0, 20, 40, 60, 80, 100}));
  EXPECT_TRUE(NiceTicks(1, 1).empty());
  EXPECT_TRUE(NiceTicks(2, 1).empty());
  EXPECT_TRUE(NiceTicks(0, kInf).empty());
  EXPECT_TRUE(NiceTicks(kNaN, 1).empty());
  EXPECT_EQ(FormatTick(0.30000000000000004, 0.1), "0.3");
  EXPECT_EQ(FormatTick(0, 0.2), "0");
  EXPECT_EQ(FormatTick(1, 0.2), "1");
  EXPECT_EQ(FormatTick(0.25, 0.25), "0.25");
  EXPECT_EQ(FormatTick(-1e-17, 0.2), "0");
  EXPECT_EQ(FormatTick(1500, 500), "1500");
}

TEST(SvgPlot, XmlEscape) {
  EXPECT_EQ(XmlEscape("a<b & c>\"d'"), "a&lt;b &amp; c&gt;&quot;d&apos;");
}

TEST(SvgPlot, LineChartEscapesAndIsWellFormed) {
  LineChart c;
  c.title = c.subtitle = c.xlabel = c.ylabel = "a<b & c";
  c.series = {{"a<b & c", {0, 0.5, 1}, {0.1, 0.4, 0.9}}, {"\"quoted\" 'name'", {0, 1}, {1, 0}}};
  std::string svg = RenderLineChart(c);
  EXPECT_TRUE(WellFormed(svg));
  EXPECT_EQ(svg.find("a<b"), std::string::npos);
  EXPECT_EQ(svg.find("& c"), std::string::npos);
  EXPECT_NE(svg.find("a&lt;b &amp; c"), std::string::npos);
  EXPECT_EQ(Count(svg, "class=\"marker\""), 5u);
  EXPECT_EQ(Count(svg, "<polyline"), 2u);
}

TEST(SvgPlot, MarkerCountMatchesFinitePoints) {
  LineChart c;
  c.series = {{"five", {1, 2, 3, 4, 5}, {1, 4, 9, 16, 25}},
              {"one", {2}, {3}},
              {"empty", {}, {}},
              {"short y", {1, 2, 3}, {5, 6}}};  // only min(x, y) sizes count
  std::string svg = RenderLineChart(c);
  EXPECT_TRUE(WellFormed(svg));
  EXPECT_EQ(Count(svg, "class=\"marker\""), 5u + 1u + 0u + 2u);
  EXPECT_EQ(Count(svg, "<polyline"), 2u);  // "one" has no line
  EXPECT_EQ(Count(svg, "<title>five: x = 3, y = 9</title>"), 1u);
}

TEST(SvgPlot, TickLabelsForUnitRange) {
  LineChart c;
  c.xlabel = "1 - precision";
  c.ylabel = "recall";
  c.xmin = c.ymin = 0;
  c.xmax = c.ymax = 1;
  c.series = {{"m", {0, 0.3, 1}, {0, 0.7, 1}}};
  std::string svg = RenderLineChart(c);
  EXPECT_TRUE(WellFormed(svg));
  const std::vector<std::string> expected = {"0", "0.2", "0.4", "0.6", "0.8", "1"};
  EXPECT_EQ(Labels(svg, "xtick"), expected);
  EXPECT_EQ(Labels(svg, "ytick"), expected);
  EXPECT_NE(svg.find("<title>m: 1 - precision = 0.3, recall = 0.7</title>"), std::string::npos);
}

TEST(SvgPlot, NonFiniteValuesAreSkippedAndBreakTheLine) {
  LineChart c;
  c.series = {{"s", {0, 1, 2, 3, 4, 5, kNaN, 7}, {1, kNaN, kInf, 2, 3, -kInf, 4, 5}}};
  std::string svg = RenderLineChart(c);
  EXPECT_TRUE(WellFormed(svg));
  EXPECT_EQ(Count(svg, "class=\"marker\""), 4u);  // x = 0, 3, 4, 7
  EXPECT_EQ(Count(svg, "<polyline"), 1u);         // only 3-4 are adjacent
  EXPECT_EQ(svg.find("nan"), std::string::npos);
  EXPECT_EQ(svg.find("inf"), std::string::npos);
}

TEST(SvgPlot, EmptyChartsRender) {
  LineChart all_nan;
  all_nan.title = "t";
  all_nan.series = {{"all nan", {kNaN, 1}, {1, kInf}}};
  for (const LineChart& c : {LineChart{}, all_nan}) {
    std::string svg = RenderLineChart(c);
    EXPECT_TRUE(WellFormed(svg));
    EXPECT_NE(svg.find(">no data<"), std::string::npos);
    EXPECT_EQ(Count(svg, "class=\"marker\""), 0u);
    EXPECT_EQ(Count(svg, "class=\"frame\""), 1u);
  }
  BarChart b;
  std::string svg = RenderBarChart(b);
  EXPECT_TRUE(WellFormed(svg));
  EXPECT_NE(svg.find(">no data<"), std::string::npos);
  b.series = {"a", "b"};
  b.groups = {{"pair 1", {kNaN}}, {"pair 2", {}}};
  svg = RenderBarChart(b);
  EXPECT_TRUE(WellFormed(svg));
  EXPECT_NE(svg.find(">no data<"), std::string::npos);
  EXPECT_EQ(Count(svg, "class=\"bar\""), 0u);
}

TEST(SvgPlot, DegenerateRanges) {
  LineChart c;
  c.series = {{"flat", {1, 2, 3}, {5, 5, 5}}, {"point", {2}, {5}}};
  std::string svg = RenderLineChart(c);
  EXPECT_TRUE(WellFormed(svg));
  EXPECT_EQ(Count(svg, "class=\"marker\""), 4u);
  auto y = Labels(svg, "ytick");
  EXPECT_NE(std::find(y.begin(), y.end(), "5"), y.end());

  c.series = {{"one point", {0.5}, {0.5}}};
  svg = RenderLineChart(c);
  EXPECT_TRUE(WellFormed(svg));
  EXPECT_EQ(Count(svg, "class=\"marker\""), 1u);

  c.series = {{"huge", {-1e308, 1e308}, {-1e308, 1e308}}};
  EXPECT_TRUE(WellFormed(RenderLineChart(c)));

  c.series = {{"s", {0, 1}, {0, 1}}};
  c.xmin = 1;  // inverted fixed bounds
  c.xmax = 0;
  c.ymin = kNaN;  // ignored
  EXPECT_TRUE(WellFormed(RenderLineChart(c)));
  c.width = c.height = -5;
  EXPECT_TRUE(WellFormed(RenderLineChart(c)));
}

TEST(SvgPlot, FixedBoundsClipData) {
  LineChart c;
  c.xmin = c.ymin = 0;
  c.xmax = c.ymax = 1;
  c.series = {{"s", {0.1, 0.5, 0.9}, {0.5, 2.0, 0.5}}};  // middle point above the panel
  std::string svg = RenderLineChart(c);
  EXPECT_TRUE(WellFormed(svg));
  EXPECT_EQ(Count(svg, "class=\"marker\""), 2u);
  EXPECT_EQ(Count(svg, "<polyline"), 2u);  // up to the top edge and back down
}

TEST(SvgPlot, DenseSeriesGetThinnedMarkers) {
  LineChart c;
  Series s{"dense", {}, {}};
  for (int i = 0; i < 1000; ++i) s.x.push_back(i), s.y.push_back(std::sin(i * 0.01));
  c.series = {s};
  EXPECT_EQ(Count(RenderLineChart(c), "class=\"marker\""), 50u);
  c.max_markers = 0;
  EXPECT_EQ(Count(RenderLineChart(c), "class=\"marker\""), 1000u);
}

TEST(SvgPlot, DistinctStylesAndLongLegend) {
  LineChart c;
  for (int i = 0; i < 8; ++i) c.series.push_back({"method " + std::to_string(i), {0, 1}, {0.1 * i, 0.2 * i}});
  c.series[3].name = std::string(300, 'x') + " tail";
  std::string svg = RenderLineChart(c);
  EXPECT_TRUE(WellFormed(svg));
  std::set<std::string> colours;
  std::regex re("stroke=\"(#[0-9a-f]{6})\" stroke-width=\"2\" stroke-linejoin");
  for (auto it = std::sregex_iterator(svg.begin(), svg.end(), re); it != std::sregex_iterator(); ++it)
    colours.insert((*it)[1]);
  EXPECT_EQ(colours.size(), 8u);
  EXPECT_NE(svg.find("\u2026"), std::string::npos);                       // shortened in the legend
  EXPECT_EQ(Count(svg, std::string(300, 'x') + " tail</title>"), 1u);  // full name as its tooltip
  EXPECT_EQ(Count(svg, "<circle"), 3u);  // only series 0 uses circles: 2 markers + legend
}

TEST(SvgPlot, ManySeriesLegendOverflow) {
  LineChart c;
  for (int i = 0; i < 40; ++i) c.series.push_back({std::string("s") + std::to_string(i), {0, 1}, {0, 1.0 * i}});
  std::string svg = RenderLineChart(c);
  EXPECT_TRUE(WellFormed(svg));
  EXPECT_NE(svg.find(" more</text>"), std::string::npos);
}

TEST(SvgPlot, BarChart) {
  BarChart b;
  b.title = "correct matches & pairs";
  b.ylabel = "correct matches";
  b.series = {"mvkp", "sift<ratio>"};
  b.groups = {{"1-2", {120, 80}}, {"1-3", {60, kNaN}}, {"1-4", {30}}, {"1-5", {0, -5}}};
  std::string svg = RenderBarChart(b);
  EXPECT_TRUE(WellFormed(svg));
  EXPECT_EQ(Count(svg, "class=\"bar\""), 6u);
  EXPECT_NE(svg.find("<title>sift&lt;ratio&gt;, 1-2: 80</title>"), std::string::npos);
  EXPECT_EQ(Labels(svg, "xtick"), (std::vector<std::string>{"1-2", "1-3", "1-4", "1-5"}));
  auto y = Labels(svg, "ytick");
  EXPECT_NE(std::find(y.begin(), y.end(), "0"), y.end());
  EXPECT_NE(std::find(y.begin(), y.end(), "100"), y.end());

  // Long and many labels: slanted, thinned, still well-formed.
  b.groups.clear();
  for (int i = 0; i < 200; ++i)
    b.groups.push_back({"a very long image pair name " + std::to_string(i), {double(i), double(200 - i)}});
  svg = RenderBarChart(b);
  EXPECT_TRUE(WellFormed(svg));
  EXPECT_EQ(Count(svg, "class=\"bar\""), 400u);
  EXPECT_NE(svg.find("rotate(-35)"), std::string::npos);
}

TEST(SvgPlot, StackCharts) {
  LineChart a;
  a.series = {{"s", {0, 1}, {0, 1}}};
  LineChart b = a;
  b.height = 300;
  std::string svg = StackCharts({RenderLineChart(a), RenderLineChart(b)});
  EXPECT_TRUE(WellFormed(svg));
  EXPECT_NE(svg.find("width=\"720\" height=\"750\""), std::string::npos);  // 440 + 10 + 300
  EXPECT_EQ(Count(svg, "class=\"marker\""), 4u);
  svg = StackCharts({RenderLineChart(a), RenderLineChart(b), RenderLineChart(a)}, 2, 0);
  EXPECT_TRUE(WellFormed(svg));
  EXPECT_NE(svg.find("width=\"1440\" height=\"880\""), std::string::npos);
  EXPECT_TRUE(WellFormed(StackCharts({})));
  EXPECT_THROW(StackCharts({"<svg>nothing</svg>"}), std::invalid_argument);
}

TEST(SvgPlot, WriteTextFile) {
  std::string path = ::testing::TempDir() + "svg_plot_test.svg";
  WriteTextFile(path, "<svg/>\n");
  std::ifstream f(path);
  std::stringstream ss;
  ss << f.rdbuf();
  EXPECT_EQ(ss.str(), "<svg/>\n");
  std::remove(path.c_str());
  try {
    WriteTextFile("/nonexistent-dir/x.svg", "x");
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent-dir/x.svg"), std::string::npos);
  }
}

}  // namespace
}  // namespace mvkp::cli
