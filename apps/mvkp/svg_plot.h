// Dependency-free SVG charts for evaluation reports (standard library only).
// The look follows bench/plot_knn.py: white background, DejaVu Sans, light
// grid, framed panel, markers, legend on the right, title + subtitle.
// Colours and marker shapes are fixed by series index (10 colours x 8 shapes;
// series 10..19 are dashed), so charts of the same method list compare.
#pragma once

#include <optional>
#include <string>
#include <vector>

namespace mvkp::cli {

// Points joined by a line with markers, in the given order. A point whose x or
// y is NaN or infinite is skipped and breaks the line. Only min(x, y) sizes
// are used.
struct Series {
  std::string name;
  std::vector<double> x, y;
};

struct LineChart {
  std::string title, subtitle, xlabel, ylabel;
  std::vector<Series> series;
  // Axis bounds; auto (data range padded by 5%, nice ticks) when empty. Data
  // outside fixed bounds is clipped.
  std::optional<double> xmin, xmax, ymin, ymax;
  int width = 720, height = 440;
  // A series with more finite points gets this many markers, evenly spread
  // (the line still joins every point); <= 0: a marker on every point.
  int max_markers = 50;
};

// The SVG document (starts with "<svg", ends with "</svg>\n"). Never throws
// for odd data: no finite point gives the frame with a "no data" note.
std::string RenderLineChart(const LineChart& c);

struct BarGroup {
  std::string label;
  std::vector<double> values;  // one per BarChart::series; missing / non-finite: no bar
};

struct BarChart {
  std::string title, subtitle, ylabel;
  std::vector<std::string> series;  // legend names
  std::vector<BarGroup> groups;     // x categories (e.g. image pairs)
  int width = 900, height = 440;
  bool value_labels = true;  // value above each bar where it fits
};

// Grouped bars from 0 (negative values go down); tooltips give the values.
std::string RenderBarChart(const BarChart& c);

// Several SVG documents from the functions above laid out in one SVG, row by
// row with `columns` per row (1: stacked vertically), `gap` pixels apart.
// Throws std::invalid_argument when a document has no width/height.
std::string StackCharts(const std::vector<std::string>& svgs, int columns = 1, int gap = 10);

// Writes `text` to `path`; throws std::runtime_error naming the path on failure.
void WriteTextFile(const std::string& path, const std::string& text);

// ---- building blocks (exposed for tests)

// &, <, >, ", ' as entities.
std::string XmlEscape(const std::string& s);
// Ticks at multiples of a step of 1, 2, 2.5 or 5 x 10^k inside [lo, hi],
// about `target` of them (empty when the range is not finite or lo >= hi).
std::vector<double> NiceTicks(double lo, double hi, int target = 6);
// A tick label: fixed decimals for the step, trailing zeros dropped ("0", "0.2", "1").
std::string FormatTick(double v, double step);

}  // namespace mvkp::cli
