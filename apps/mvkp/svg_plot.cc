#include "svg_plot.h"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <functional>
#include <numbers>
#include <stdexcept>
#include <utility>

namespace mvkp::cli {
namespace {

constexpr const char* kFont = "DejaVu Sans, Arial, Helvetica, sans-serif";
constexpr const char* kColours[] = {"#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd",
                                    "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf"};
constexpr int kNumColours = 10;
constexpr int kNumShapes = 8;
constexpr double kCharW = 0.62;  // average DejaVu Sans advance, in em

// Frame of a panel and a legend column, in pixels.
constexpr double kMarginL = 70, kMarginR = 16, kMarginB = 48, kLegendW = 190;

// Locale-independent fixed-point number.
std::string Num(double v, int decimals = 1) {
  if (!std::isfinite(v)) return "0";
  char buf[64];
  auto r = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::fixed, decimals);
  if (r.ec != std::errc()) return "0";
  std::string s(buf, r.ptr);
  if (s.find('.') != std::string::npos) {
    while (s.back() == '0') s.pop_back();
    if (s.back() == '.') s.pop_back();
  }
  if (s == "-0") s = "0";
  return s;
}

// Short value for tooltips and bar labels: integers as such, else 4 significant digits.
std::string FormatValue(double v) {
  if (std::isnan(v)) return "nan";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  if (v == std::floor(v) && std::fabs(v) < 1e15) return Num(v, 0);
  char buf[64];
  auto r = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::general, 4);
  return r.ec == std::errc() ? std::string(buf, r.ptr) : "?";
}

// UTF-8 code points of a string (continuation bytes not counted).
std::vector<std::string> CodePoints(const std::string& s) {
  std::vector<std::string> cps;
  for (unsigned char ch : s) {
    if ((ch & 0xC0) == 0x80 && !cps.empty())
      cps.back() += static_cast<char>(ch);
    else
      cps.emplace_back(1, static_cast<char>(ch));
  }
  return cps;
}

std::string Join(const std::vector<std::string>& cps, size_t from, size_t to) {
  std::string s;
  for (size_t i = from; i < to && i < cps.size(); ++i) s += cps[i];
  return s;
}

// Greedy word wrap to at most `max_lines` lines of `max_chars` code points;
// what does not fit ends the last line with an ellipsis.
std::vector<std::string> Wrap(const std::string& text, int max_chars, int max_lines) {
  max_chars = std::max(max_chars, 2);
  max_lines = std::max(max_lines, 1);
  std::vector<std::string> cps = CodePoints(text);
  for (auto& c : cps)
    if (c == "\n" || c == "\t" || c == "\r") c = " ";
  std::vector<std::string> lines;
  size_t i = 0;
  while (i < cps.size() && cps[i] == " ") ++i;
  while (i < cps.size()) {
    size_t remaining = cps.size() - i;
    if (remaining <= static_cast<size_t>(max_chars)) {
      lines.push_back(Join(cps, i, cps.size()));
      break;
    }
    if (static_cast<int>(lines.size()) == max_lines - 1) {
      lines.push_back(Join(cps, i, i + max_chars - 1) + "\u2026");
      break;
    }
    // Break at the last space within the limit, else mid-word.
    size_t end = i + max_chars;
    size_t brk = end;
    while (brk > i && cps[brk] != " ") --brk;
    if (brk == i) brk = end;
    std::string line = Join(cps, i, brk);
    while (!line.empty() && line.back() == ' ') line.pop_back();
    lines.push_back(line);
    i = brk;
    while (i < cps.size() && cps[i] == " ") ++i;
  }
  return lines;
}

std::string Fit(const std::string& text, double width_px, double font_px) {
  auto lines = Wrap(text, static_cast<int>(width_px / (kCharW * font_px)), 1);
  return lines.empty() ? std::string() : lines[0];
}

std::string Text(double x, double y, const std::string& text, int size, const std::string& extra = "") {
  return "<text x=\"" + Num(x) + "\" y=\"" + Num(y) + "\" font-size=\"" + std::to_string(size) + "\"" +
         (extra.empty() ? "" : " " + extra) + ">" + XmlEscape(text) + "</text>\n";
}

std::string Colour(size_t i) { return kColours[i % kNumColours]; }
bool Dashed(size_t i) { return (i / kNumColours) % 2 == 1; }

std::string Points(const std::vector<std::pair<double, double>>& pts) {
  std::string s;
  for (const auto& [x, y] : pts) {
    if (!s.empty()) s += ' ';
    s += Num(x) + "," + Num(y);
  }
  return s;
}

// A filled marker shape centred at (x, y); shape by series index.
std::string Marker(size_t index, double x, double y, const std::string& colour, double r = 4.0) {
  const std::string fill = " fill=\"" + colour + "\"";
  std::vector<std::pair<double, double>> p;
  switch (index % kNumShapes) {
    case 0:
      return "<circle cx=\"" + Num(x) + "\" cy=\"" + Num(y) + "\" r=\"" + Num(r) + "\"" + fill + "/>";
    case 1:
      return "<rect x=\"" + Num(x - 0.9 * r) + "\" y=\"" + Num(y - 0.9 * r) + "\" width=\"" + Num(1.8 * r) +
             "\" height=\"" + Num(1.8 * r) + "\"" + fill + "/>";
    case 2:  // triangle up
      p = {{x, y - 1.25 * r}, {x - 1.1 * r, y + 0.8 * r}, {x + 1.1 * r, y + 0.8 * r}};
      break;
    case 3:  // diamond
      p = {{x, y - 1.3 * r}, {x + r, y}, {x, y + 1.3 * r}, {x - r, y}};
      break;
    case 4:  // triangle down
      p = {{x, y + 1.25 * r}, {x - 1.1 * r, y - 0.8 * r}, {x + 1.1 * r, y - 0.8 * r}};
      break;
    case 5: {  // plus
      double a = 1.15 * r, w = 0.42 * r;
      p = {{x - w, y - a}, {x + w, y - a}, {x + w, y - w}, {x + a, y - w}, {x + a, y + w}, {x + w, y + w},
           {x + w, y + a}, {x - w, y + a}, {x - w, y + w}, {x - a, y + w}, {x - a, y - w}, {x - w, y - w}};
      break;
    }
    case 6:  // five-pointed star
      for (int k = 0; k < 10; ++k) {
        double ang = -std::numbers::pi / 2 + k * std::numbers::pi / 5, rad = (k % 2 ? 0.55 : 1.4) * r;
        p.emplace_back(x + rad * std::cos(ang), y + rad * std::sin(ang));
      }
      break;
    default:  // hexagon
      for (int k = 0; k < 6; ++k) {
        double ang = k * std::numbers::pi / 3;
        p.emplace_back(x + 1.1 * r * std::cos(ang), y + 1.1 * r * std::sin(ang));
      }
  }
  return "<polygon points=\"" + Points(p) + "\"" + fill + "/>";
}

std::string Header(int w, int h) {
  return "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" + std::to_string(w) + "\" height=\"" +
         std::to_string(h) + "\" viewBox=\"0 0 " + std::to_string(w) + " " + std::to_string(h) +
         "\" font-family=\"" + kFont + "\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
}

// Title (one line) and subtitle (up to two lines) in the top-left corner;
// returns the y where the panel may start.
double Heading(std::string& svg, const std::string& title, const std::string& subtitle, int width) {
  double y = 0;
  if (!title.empty()) {
    svg += Text(12, 22, Fit(title, width - 24, 15), 15, "font-weight=\"bold\"");
    y = 22;
  }
  if (!subtitle.empty()) {
    for (const auto& line : Wrap(subtitle, static_cast<int>((width - 24) / (kCharW * 11)), 2)) {
      y += y == 0 ? 18 : (y == 22 ? 18 : 14);
      svg += Text(12, y, line, 11, "fill=\"#444\"");
    }
  }
  return y == 0 ? 16 : y + 16;
}

// Legend entries at the right: `swatch(i, x, y)` draws the key of entry i.
template <typename Swatch>
void Legend(std::string& svg, const std::vector<std::string>& names, double x, double y, double height,
            Swatch swatch) {
  const int max_chars = static_cast<int>((kLegendW - 50) / (kCharW * 12));
  double bottom = y + height;
  svg += "<g class=\"legend\">\n";
  for (size_t i = 0; i < names.size(); ++i) {
    auto lines = Wrap(names[i].empty() ? "(unnamed)" : names[i], max_chars, 2);
    if (lines.empty()) lines.push_back("");
    double need = 22 + 14 * (lines.size() - 1);
    if (y + need > bottom && i + 1 < names.size()) {
      svg += Text(x, y + 4, "+" + std::to_string(names.size() - i) + " more", 11, "fill=\"#666\"");
      break;
    }
    svg += "<g><title>" + XmlEscape(names[i]) + "</title>";
    svg += swatch(i, x, y);
    for (size_t l = 0; l < lines.size(); ++l) svg += Text(x + 42, y + 4 + 14 * l, lines[l], 12);
    svg += "</g>\n";
    y += need;
  }
  svg += "</g>\n";
}

struct Range {
  double lo = 0, hi = 1;
  bool fixed_lo = false, fixed_hi = false;
};

// Axis range from finite data and optional fixed bounds: padded by 5% on the
// automatic sides, widened when empty or degenerate.
Range MakeRange(double dlo, double dhi, bool have_data, std::optional<double> lo, std::optional<double> hi) {
  Range r;
  r.fixed_lo = lo && std::isfinite(*lo);
  r.fixed_hi = hi && std::isfinite(*hi);
  if (!have_data) dlo = 0, dhi = 1;
  r.lo = r.fixed_lo ? *lo : dlo;
  r.hi = r.fixed_hi ? *hi : dhi;
  if (r.fixed_lo && !r.fixed_hi && r.hi <= r.lo) r.hi = r.lo + std::max(1.0, std::fabs(r.lo) * 0.1);
  if (r.fixed_hi && !r.fixed_lo && r.lo >= r.hi) r.lo = r.hi - std::max(1.0, std::fabs(r.hi) * 0.1);
  double span = r.hi - r.lo;
  double scale = std::max(std::fabs(r.lo), std::fabs(r.hi));
  if (!(span > 1e-12 * scale) || !std::isfinite(span)) {  // equal, inverted or overflowing
    double mid = r.lo / 2 + r.hi / 2;
    if (!std::isfinite(mid)) mid = 0;
    double d = mid == 0 ? 0.5 : std::fabs(mid) * 0.1;
    r = Range{mid - d, mid + d, false, false};
    return r;
  }
  if (!r.fixed_lo) r.lo -= 0.05 * span;
  if (!r.fixed_hi) r.hi += 0.05 * span;
  if (!std::isfinite(r.hi - r.lo)) r = Range{-1e307, 1e307};
  return r;
}

double TickStep(const std::vector<double>& ticks, double lo, double hi) {
  return ticks.size() >= 2 ? ticks[1] - ticks[0] : std::max(std::fabs(hi - lo), 1e-300);
}

// Liang-Barsky: clips a-b to the box; false when outside. Sets whether each end moved.
bool Clip(double x0, double y0, double x1, double y1, double bx0, double by0, double bx1, double by1,
          std::pair<double, double>* a, std::pair<double, double>* b, bool* a_cut, bool* b_cut) {
  double t0 = 0, t1 = 1, dx = x1 - x0, dy = y1 - y0;
  const double p[4] = {-dx, dx, -dy, dy}, q[4] = {x0 - bx0, bx1 - x0, y0 - by0, by1 - y0};
  for (int k = 0; k < 4; ++k) {
    if (p[k] == 0) {
      if (q[k] < 0) return false;
    } else {
      double t = q[k] / p[k];
      if (p[k] < 0) t0 = std::max(t0, t);
      else t1 = std::min(t1, t);
    }
  }
  if (t0 > t1) return false;
  *a = {x0 + t0 * dx, y0 + t0 * dy};
  *b = {x0 + t1 * dx, y0 + t1 * dy};
  *a_cut = t0 > 0;
  *b_cut = t1 < 1;
  return true;
}

void Frame(std::string& svg, double x, double y, double w, double h) {
  svg += "<rect class=\"frame\" x=\"" + Num(x) + "\" y=\"" + Num(y) + "\" width=\"" + Num(w) + "\" height=\"" +
         Num(h) + "\" fill=\"none\" stroke=\"#444\"/>\n";
}

void NoData(std::string& svg, double px0, double py0, double pw, double ph) {
  svg += Text(px0 + pw / 2, py0 + ph / 2, "no data", 12, "text-anchor=\"middle\" fill=\"#666\"");
}

void YAxisLabel(std::string& svg, const std::string& label, double x, double py0, double ph) {
  if (label.empty()) return;
  svg += "<text transform=\"translate(" + Num(x) + "," + Num(py0 + ph / 2) +
         ") rotate(-90)\" font-size=\"12\" text-anchor=\"middle\">" + XmlEscape(Fit(label, ph, 12)) + "</text>\n";
}

// Horizontal grid lines and labels for y ticks.
void YTicks(std::string& svg, const std::vector<double>& ticks, double step, double px0, double pw,
            const std::function<double(double)>& Y) {
  for (double t : ticks) {
    double y = Y(t);
    svg += "<line x1=\"" + Num(px0) + "\" y1=\"" + Num(y) + "\" x2=\"" + Num(px0 + pw) + "\" y2=\"" + Num(y) +
           "\" stroke=\"#e3e3e3\"/>\n";
    svg += Text(px0 - 6, y + 4, FormatTick(t, step), 11, "text-anchor=\"end\" class=\"ytick\"");
  }
}

}  // namespace

std::string XmlEscape(const std::string& s) {
  std::string out;
  out.reserve(s.size());
  for (char ch : s) {
    switch (ch) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      case '\'': out += "&apos;"; break;
      default:
        // Control characters other than tab/newline are not allowed in XML 1.0.
        if (static_cast<unsigned char>(ch) < 0x20 && ch != '\t' && ch != '\n' && ch != '\r')
          out += ' ';
        else
          out += ch;
    }
  }
  return out;
}

std::vector<double> NiceTicks(double lo, double hi, int target) {
  std::vector<double> ticks;
  if (!std::isfinite(lo) || !std::isfinite(hi) || !(hi > lo) || !std::isfinite(hi - lo)) return ticks;
  target = std::clamp(target, 2, 50);
  double raw = (hi - lo) / target;
  double mag = std::pow(10.0, std::floor(std::log10(raw)));
  if (!(mag > 0) || !std::isfinite(mag)) return ticks;
  double step = 10 * mag;
  for (double m : {1.0, 2.0, 2.5, 5.0, 10.0})
    if (m * mag >= raw * (1 - 1e-9)) {
      step = m * mag;
      break;
    }
  const double eps = 1e-9;
  double first = std::ceil(lo / step - eps), last = std::floor(hi / step + eps);
  for (double i = first; i <= last && ticks.size() < 200; i += 1) ticks.push_back(i * step);
  return ticks;
}

std::string FormatTick(double v, double step) {
  if (!std::isfinite(v)) return FormatValue(v);
  if (!(step > 0) || !std::isfinite(step)) return FormatValue(v);
  if (std::fabs(v) >= 1e7 || step < 1e-6) {
    char buf[64];
    auto r = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::general, 6);
    return r.ec == std::errc() ? std::string(buf, r.ptr) : "?";
  }
  // Decimals of the step (2.5 x 10^k needs one more), trailing zeros dropped.
  int decimals = std::max(0, static_cast<int>(-std::floor(std::log10(step) + 1e-9)) + 1);
  if (std::fabs(v) < step * 1e-6) v = 0;
  return Num(v, std::min(decimals, 12));
}

std::string RenderLineChart(const LineChart& c) {
  const int W = std::max(c.width, 240), H = std::max(c.height, 160);
  std::string svg = Header(W, H);
  const double top = Heading(svg, c.title, c.subtitle, W);

  bool any_name = false;
  double xlo = HUGE_VAL, xhi = -HUGE_VAL, ylo = HUGE_VAL, yhi = -HUGE_VAL;
  for (const auto& s : c.series) {
    any_name |= !s.name.empty();
    for (size_t i = 0; i < std::min(s.x.size(), s.y.size()); ++i) {
      if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i])) continue;
      xlo = std::min(xlo, s.x[i]), xhi = std::max(xhi, s.x[i]);
      ylo = std::min(ylo, s.y[i]), yhi = std::max(yhi, s.y[i]);
    }
  }
  const bool have_data = xlo <= xhi;
  const double legend_w = any_name ? kLegendW : 0;
  const double px0 = kMarginL, py0 = top;
  const double pw = std::max(40.0, W - kMarginL - kMarginR - legend_w);
  const double ph = std::max(40.0, H - top - kMarginB);

  svg += "<rect x=\"" + Num(px0) + "\" y=\"" + Num(py0) + "\" width=\"" + Num(pw) + "\" height=\"" + Num(ph) +
         "\" fill=\"white\"/>\n";
  const Range xr = MakeRange(xlo, xhi, have_data, c.xmin, c.xmax);
  const Range yr = MakeRange(ylo, yhi, have_data, c.ymin, c.ymax);
  auto X = [&](double v) { return px0 + (v - xr.lo) / (xr.hi - xr.lo) * pw; };
  auto Y = [&](double v) { return py0 + ph - (v - yr.lo) / (yr.hi - yr.lo) * ph; };

  // Grid and tick labels (for an empty chart only on axes with fixed bounds).
  svg += "<g class=\"axes\">\n";
  if (have_data || (xr.fixed_lo && xr.fixed_hi)) {
    auto xt = NiceTicks(xr.lo, xr.hi, std::clamp(static_cast<int>(pw / 80), 3, 10));
    double step = TickStep(xt, xr.lo, xr.hi);
    for (double t : xt) {
      double x = X(t);
      svg += "<line x1=\"" + Num(x) + "\" y1=\"" + Num(py0) + "\" x2=\"" + Num(x) + "\" y2=\"" + Num(py0 + ph) +
             "\" stroke=\"#e3e3e3\"/>\n";
      svg += Text(x, py0 + ph + 16, FormatTick(t, step), 11, "text-anchor=\"middle\" class=\"xtick\"");
    }
  }
  if (have_data || (yr.fixed_lo && yr.fixed_hi)) {
    auto yt = NiceTicks(yr.lo, yr.hi, std::clamp(static_cast<int>(ph / 50), 3, 10));
    YTicks(svg, yt, TickStep(yt, yr.lo, yr.hi), px0, pw, Y);
  }
  if (!c.xlabel.empty())
    svg += Text(px0 + pw / 2, py0 + ph + 36, Fit(c.xlabel, pw, 12), 12, "text-anchor=\"middle\"");
  YAxisLabel(svg, c.ylabel, 18, py0, ph);
  svg += "</g>\n";

  // Lines (clipped to the panel, broken at non-finite points), then markers.
  const double tol = 0.5, bx0 = px0 - tol, by0 = py0 - tol, bx1 = px0 + pw + tol, by1 = py0 + ph + tol;
  for (size_t si = 0; si < c.series.size(); ++si) {
    const Series& s = c.series[si];
    const std::string colour = Colour(si);
    const size_t n = std::min(s.x.size(), s.y.size());
    std::vector<size_t> finite;
    for (size_t i = 0; i < n; ++i)
      if (std::isfinite(s.x[i]) && std::isfinite(s.y[i])) finite.push_back(i);
    svg += "<g class=\"series\">\n";
    std::vector<std::vector<std::pair<double, double>>> lines(1);
    auto flush = [&] {
      if (lines.back().size() >= 2) lines.emplace_back();
      else lines.back().clear();
    };
    for (size_t i = 0; i + 1 < n; ++i) {
      bool ok0 = std::isfinite(s.x[i]) && std::isfinite(s.y[i]);
      bool ok1 = std::isfinite(s.x[i + 1]) && std::isfinite(s.y[i + 1]);
      if (!ok0 || !ok1) {
        flush();
        continue;
      }
      std::pair<double, double> a, b;
      bool a_cut, b_cut;
      if (!Clip(X(s.x[i]), Y(s.y[i]), X(s.x[i + 1]), Y(s.y[i + 1]), bx0, by0, bx1, by1, &a, &b, &a_cut, &b_cut)) {
        flush();
        continue;
      }
      auto& cur = lines.back();
      if (cur.empty() || a_cut) {
        flush();
        lines.back() = {a, b};
      } else {
        cur.push_back(b);
      }
      if (b_cut) flush();
    }
    const std::string dash = Dashed(si) ? " stroke-dasharray=\"6,4\"" : "";
    for (const auto& l : lines)
      if (l.size() >= 2)
        svg += "<polyline fill=\"none\" stroke=\"" + colour + "\" stroke-width=\"2\" stroke-linejoin=\"round\"" +
               dash + " points=\"" + Points(l) + "\"/>\n";

    std::vector<size_t> shown = finite;
    if (c.max_markers > 0 && finite.size() > static_cast<size_t>(c.max_markers)) {
      shown.clear();
      const size_t m = static_cast<size_t>(c.max_markers);
      for (size_t j = 0; j < m; ++j) {
        size_t k = m == 1 ? 0 : static_cast<size_t>(std::llround(double(j) * (finite.size() - 1) / (m - 1)));
        if (shown.empty() || shown.back() != finite[k]) shown.push_back(finite[k]);
      }
    }
    const std::string xname = c.xlabel.empty() ? "x" : c.xlabel, yname = c.ylabel.empty() ? "y" : c.ylabel;
    for (size_t i : shown) {
      double x = X(s.x[i]), y = Y(s.y[i]);
      if (x < bx0 || x > bx1 || y < by0 || y > by1) continue;
      std::string tip = (s.name.empty() ? "" : s.name + ": ") + xname + " = " + FormatValue(s.x[i]) + ", " +
                        yname + " = " + FormatValue(s.y[i]);
      svg += "<g class=\"marker\">" + Marker(si, x, y, colour) + "<title>" + XmlEscape(tip) + "</title></g>\n";
    }
    svg += "</g>\n";
  }
  if (!have_data) NoData(svg, px0, py0, pw, ph);
  Frame(svg, px0, py0, pw, ph);

  if (any_name) {
    std::vector<std::string> names;
    for (const auto& s : c.series) names.push_back(s.name);
    Legend(svg, names, px0 + pw + 14, py0 + 10, H - py0 - 20, [&](size_t i, double x, double y) {
      return "<line x1=\"" + Num(x) + "\" y1=\"" + Num(y) + "\" x2=\"" + Num(x + 34) + "\" y2=\"" + Num(y) +
             "\" stroke=\"" + Colour(i) + "\" stroke-width=\"2\"" +
             (Dashed(i) ? " stroke-dasharray=\"6,4\"" : "") + "/>" + Marker(i, x + 17, y, Colour(i));
    });
  }
  svg += "</svg>\n";
  return svg;
}

std::string RenderBarChart(const BarChart& c) {
  const int W = std::max(c.width, 240), H = std::max(c.height, 160);
  std::string svg = Header(W, H);
  const double top = Heading(svg, c.title, c.subtitle, W);
  const size_t ns = c.series.size(), ng = c.groups.size();

  double vlo = HUGE_VAL, vhi = -HUGE_VAL;
  for (const auto& g : c.groups)
    for (size_t i = 0; i < std::min(ns, g.values.size()); ++i)
      if (std::isfinite(g.values[i])) vlo = std::min(vlo, g.values[i]), vhi = std::max(vhi, g.values[i]);
  const bool have_data = vlo <= vhi;

  bool any_name = false;
  for (const auto& s : c.series) any_name |= !s.empty();
  const double legend_w = any_name ? kLegendW : 0;
  const double px0 = kMarginL, py0 = top;
  const double pw = std::max(40.0, W - kMarginL - kMarginR - legend_w);
  const double group_w = ng ? pw / ng : pw;

  // Category labels: horizontal when they fit, else slanted and shortened;
  // every k-th label when the groups are very narrow.
  size_t longest = 0;
  for (const auto& g : c.groups) longest = std::max(longest, CodePoints(g.label).size());
  const bool slant = longest * kCharW * 11 > group_w - 4;
  const size_t slant_chars = std::min<size_t>(longest, 18);
  const double bottom = slant ? 24 + slant_chars * kCharW * 11 * 0.57 + 8 : kMarginB;
  const double ph = std::max(40.0, H - top - bottom);
  const size_t label_every = std::max<size_t>(1, static_cast<size_t>(std::ceil(14.0 / group_w)));

  svg += "<rect x=\"" + Num(px0) + "\" y=\"" + Num(py0) + "\" width=\"" + Num(pw) + "\" height=\"" + Num(ph) +
         "\" fill=\"white\"/>\n";
  double lo = have_data ? std::min(0.0, vlo) : 0, hi = have_data ? std::max(0.0, vhi) : 1;
  if (!(hi > lo) || !std::isfinite(hi - lo)) hi = lo + 1;
  // Room above (and below) the bars for value labels.
  const double span = hi - lo;
  if (hi > 0) hi += 0.08 * span;
  if (lo < 0) lo -= 0.08 * span;
  auto Y = [&](double v) { return py0 + ph - (v - lo) / (hi - lo) * ph; };

  svg += "<g class=\"axes\">\n";
  if (have_data) {
    auto yt = NiceTicks(lo, hi, std::clamp(static_cast<int>(ph / 50), 3, 10));
    YTicks(svg, yt, TickStep(yt, lo, hi), px0, pw, Y);
  }
  for (size_t gi = 0; gi < ng; gi += label_every) {
    double x = px0 + (gi + 0.5) * group_w, y = py0 + ph + 16;
    const std::string& label = c.groups[gi].label;
    if (!slant) {
      svg += Text(x, y, label, 11, "text-anchor=\"middle\" class=\"xtick\"");
    } else {
      svg += "<text transform=\"translate(" + Num(x + 3) + "," + Num(y - 6) +
             ") rotate(-35)\" font-size=\"11\" text-anchor=\"end\" class=\"xtick\">" +
             XmlEscape(Wrap(label, static_cast<int>(slant_chars), 1).front()) + "<title>" + XmlEscape(label) +
             "</title></text>\n";
    }
  }
  YAxisLabel(svg, c.ylabel, 18, py0, ph);
  svg += "</g>\n";

  // Bars: 80% of each group, one slot per series.
  const double inner = group_w * 0.8, bar_w = ns ? inner / ns : 0;
  const double y0 = Y(0);
  svg += "<g class=\"bars\">\n";
  for (size_t gi = 0; gi < ng; ++gi) {
    const BarGroup& g = c.groups[gi];
    for (size_t si = 0; si < std::min(ns, g.values.size()); ++si) {
      double v = g.values[si];
      if (!std::isfinite(v)) continue;
      double x = px0 + gi * group_w + 0.1 * group_w + si * bar_w, y = Y(v);
      double ytop = std::min(y, y0), h = std::fabs(y - y0);
      std::string tip = (c.series[si].empty() ? "" : c.series[si] + ", ") + g.label + ": " + FormatValue(v);
      svg += "<rect class=\"bar\" x=\"" + Num(x, 2) + "\" y=\"" + Num(ytop, 2) + "\" width=\"" +
             Num(std::max(bar_w - (bar_w > 4 ? 1 : 0), 0.5), 2) + "\" height=\"" + Num(std::max(h, 0.5), 2) +
             "\" fill=\"" + Colour(si) + "\"" + (Dashed(si) ? " fill-opacity=\"0.55\"" : "") + "><title>" +
             XmlEscape(tip) + "</title></rect>\n";
      std::string text = FormatValue(v);
      if (c.value_labels && text.size() * kCharW * 9 <= bar_w + 2)
        svg += Text(x + bar_w / 2, v >= 0 ? y - 3 : y + 10, text, 9, "text-anchor=\"middle\" fill=\"#333\"");
    }
  }
  svg += "</g>\n";
  if (have_data && lo < 0)
    svg += "<line x1=\"" + Num(px0) + "\" y1=\"" + Num(y0) + "\" x2=\"" + Num(px0 + pw) + "\" y2=\"" + Num(y0) +
           "\" stroke=\"#444\"/>\n";
  if (!have_data) NoData(svg, px0, py0, pw, ph);
  Frame(svg, px0, py0, pw, ph);

  if (any_name)
    Legend(svg, c.series, px0 + pw + 14, py0 + 10, H - py0 - 20, [&](size_t i, double x, double y) {
      return "<rect x=\"" + Num(x + 8) + "\" y=\"" + Num(y - 7) + "\" width=\"18\" height=\"14\" fill=\"" +
             Colour(i) + "\"" + (Dashed(i) ? " fill-opacity=\"0.55\"" : "") + "/>";
    });
  svg += "</svg>\n";
  return svg;
}

namespace {
// width="..." / height="..." of the root element.
double RootAttr(const std::string& svg, const std::string& name) {
  size_t start = svg.find("<svg");
  size_t end = svg.find('>', start);
  if (start == std::string::npos || end == std::string::npos) return -1;
  std::string tag = svg.substr(start, end - start);
  for (char q : {'"', '\''}) {
    size_t p = tag.find(" " + name + "=" + q);
    if (p == std::string::npos) continue;
    p += name.size() + 3;
    try {
      return std::stod(tag.substr(p, tag.find(q, p) - p));
    } catch (const std::exception&) {
      return -1;
    }
  }
  return -1;
}
}  // namespace

std::string StackCharts(const std::vector<std::string>& svgs, int columns, int gap) {
  columns = std::max(columns, 1);
  gap = std::max(gap, 0);
  if (svgs.empty()) {
    std::string svg = Header(240, 60);
    svg += Text(120, 34, "no charts", 12, "text-anchor=\"middle\" fill=\"#666\"") + "</svg>\n";
    return svg;
  }
  std::vector<double> w(svgs.size()), h(svgs.size());
  for (size_t i = 0; i < svgs.size(); ++i) {
    w[i] = RootAttr(svgs[i], "width");
    h[i] = RootAttr(svgs[i], "height");
    if (!(w[i] > 0) || !(h[i] > 0))
      throw std::invalid_argument("StackCharts: document " + std::to_string(i) + " has no width/height");
  }
  const size_t cols = static_cast<size_t>(columns);
  std::vector<double> col_w(cols, 0);
  std::vector<double> row_h((svgs.size() + cols - 1) / cols, 0);
  for (size_t i = 0; i < svgs.size(); ++i) {
    col_w[i % cols] = std::max(col_w[i % cols], w[i]);
    row_h[i / cols] = std::max(row_h[i / cols], h[i]);
  }
  double total_w = gap * (std::min(cols, svgs.size()) - 1.0), total_h = gap * (row_h.size() - 1.0);
  for (double v : col_w) total_w += v;
  for (double v : row_h) total_h += v;
  std::string out = Header(static_cast<int>(std::ceil(total_w)), static_cast<int>(std::ceil(total_h)));
  double y = 0;
  for (size_t r = 0; r < row_h.size(); ++r) {
    double x = 0;
    for (size_t k = 0; k < cols && r * cols + k < svgs.size(); ++k) {
      std::string doc = svgs[r * cols + k];
      size_t start = doc.find("<svg");  // drops an XML declaration if any
      out += "<g transform=\"translate(" + Num(x) + "," + Num(y) + ")\">\n" + doc.substr(start);
      if (out.back() != '\n') out += '\n';
      out += "</g>\n";
      x += col_w[k] + gap;
    }
    y += row_h[r] + gap;
  }
  out += "</svg>\n";
  return out;
}

void WriteTextFile(const std::string& path, const std::string& text) {
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  if (!f) throw std::runtime_error("cannot write " + path + ": " + std::strerror(errno));
  f.write(text.data(), static_cast<std::streamsize>(text.size()));
  f.close();
  if (!f) throw std::runtime_error("cannot write " + path + ": " + std::strerror(errno));
}

}  // namespace mvkp::cli
