#include "bench/soak/plot.h"

#include <algorithm>
#include <cmath>

#include "absl/strings/str_format.h"

namespace shapeid::soak {
namespace {

double NiceStep(double range, int ticks) {
  const double raw = range / ticks;
  const double power = std::pow(10.0, std::floor(std::log10(raw)));
  const double f = raw / power;
  return (f <= 1 ? 1 : f <= 2 ? 2 : f <= 5 ? 5 : 10) * power;
}

std::string Escape(const std::string& text) {
  std::string out;
  for (char c : text) {
    if (c == '<') {
      out += "&lt;";
    } else if (c == '>') {
      out += "&gt;";
    } else if (c == '&') {
      out += "&amp;";
    } else {
      out += c;
    }
  }
  return out;
}

// One panel: a frame, x ticks over [0, x_max], y ticks, labels. `y_of` maps a value to pixels.
struct Panel {
  double left, top, width, height, x_max;
  double X(double t) const { return left + width * t / x_max; }
};

void XAxis(std::string& svg, const Panel& p) {
  const double step = NiceStep(p.x_max, 8);
  for (double t = 0; t <= p.x_max + 1e-9; t += step) {
    absl::StrAppendFormat(&svg,
                          R"(<line x1="%.1f" y1="%.1f" x2="%.1f" y2="%.1f" stroke="#ddd"/>)"
                          R"(<text x="%.1f" y="%.1f" text-anchor="middle">%g</text>)"
                          "\n",
                          p.X(t), p.top, p.X(t), p.top + p.height, p.X(t), p.top + p.height + 16,
                          t);
  }
  absl::StrAppendFormat(&svg,
                        R"(<text x="%.1f" y="%.1f" text-anchor="middle">%s</text>)"
                        "\n",
                        p.left + p.width / 2, p.top + p.height + 36,
                        "time since the load started (s)");
}

void YLabel(std::string& svg, const Panel& p, const std::string& label) {
  const double cy = p.top + p.height / 2;
  absl::StrAppendFormat(&svg,
                        R"(<text x="%.1f" y="%.1f" text-anchor="middle" )"
                        R"svg(transform="rotate(-90 %.1f %.1f)">%s</text>)svg"
                        "\n",
                        p.left - 58, cy, p.left - 58, cy, Escape(label));
}

void Frame(std::string& svg, const Panel& p, const std::string& title) {
  absl::StrAppendFormat(&svg,
                        R"(<rect x="%.1f" y="%.1f" width="%.1f" height="%.1f" fill="none" )"
                        R"(stroke="#333"/>)"
                        "\n"
                        R"(<text x="%.1f" y="%.1f" font-weight="bold">%s</text>)"
                        "\n",
                        p.left, p.top, p.width, p.height, p.left, p.top - 8, Escape(title));
}

void WarmupLine(std::string& svg, const Panel& p, double warmup_end) {
  absl::StrAppendFormat(&svg,
                        R"(<line x1="%.1f" y1="%.1f" x2="%.1f" y2="%.1f" stroke="#888" )"
                        R"(stroke-dasharray="4 3"/>)"
                        R"(<text x="%.1f" y="%.1f" fill="#666">end of warm-up</text>)"
                        "\n",
                        p.X(warmup_end), p.top, p.X(warmup_end), p.top + p.height,
                        p.X(warmup_end) + 4, p.top + 14);
}

template <typename YOf>
void Polyline(std::string& svg, const Panel& p, const std::vector<Window>& windows,
              const char* color, const YOf& y_of, const std::string& first_point = "") {
  std::string points = first_point;
  for (const Window& w : windows) {
    if (w.requests == 0 && w.rss_kib == 0) continue;
    const double y = y_of(w);
    if (!std::isfinite(y)) continue;
    absl::StrAppendFormat(&points, "%.1f,%.1f ", p.X(w.t1), y);
  }
  absl::StrAppendFormat(&svg,
                        R"(<polyline points="%s" fill="none" stroke="%s" stroke-width="1.8"/>)"
                        "\n",
                        points, color);
}

void Legend(std::string& svg, const Panel& p, int row, const char* color, const std::string& text) {
  const double x = p.left + p.width - 190, y = p.top + 18 + 18 * row;
  absl::StrAppendFormat(&svg, R"(<rect x="%.1f" y="%.1f" width="180" height="18" fill="white"/>)",
                        x - 4, y - 13);
  absl::StrAppendFormat(&svg,
                        R"(<line x1="%.1f" y1="%.1f" x2="%.1f" y2="%.1f" stroke="%s" )"
                        R"(stroke-width="2.5"/><text x="%.1f" y="%.1f">%s</text>)"
                        "\n",
                        x, y - 4, x + 24, y - 4, color, x + 30, y, Escape(text));
}

}  // namespace

std::string Plot(const std::vector<Window>& windows, double warmup_end, int64_t rss_start_kib,
                 int64_t rss_warm_kib, double max_growth_percent, const std::string& title,
                 const std::string& subtitle) {
  const double width = 960, height = 700;
  const double x_max = windows.empty() ? 1 : windows.back().t1;
  std::string svg = absl::StrFormat(
      R"(<svg xmlns="http://www.w3.org/2000/svg" width="%.0f" height="%.0f" )"
      R"(viewBox="0 0 %.0f %.0f" font-family="sans-serif" font-size="12">)"
      "\n"
      R"(<rect width="100%%" height="100%%" fill="white"/>)"
      "\n"
      R"(<text x="%.0f" y="26" text-anchor="middle" font-size="16" font-weight="bold">%s</text>)"
      "\n"
      R"(<text x="%.0f" y="46" text-anchor="middle" fill="#444">%s</text>)"
      "\n",
      width, height, width, height, width / 2, Escape(title), width / 2, Escape(subtitle));

  // Latency, log scale over whole decades.
  const Panel lat{90, 90, width - 130, 230, x_max};
  double lo = 1e300, hi = 0;
  for (const Window& w : windows) {
    if (w.requests == 0) continue;
    lo = std::min(lo, w.p50_ms);
    hi = std::max(hi, w.p99_ms);
  }
  if (hi <= 0) lo = 0.1, hi = 1;
  const double d_lo = std::floor(std::log10(std::max(lo, 1e-3)));
  const double d_hi = std::max(d_lo + 1, std::ceil(std::log10(hi)));
  auto lat_y = [&](double ms) {
    return lat.top + lat.height * (1 - (std::log10(ms) - d_lo) / (d_hi - d_lo));
  };
  Frame(svg, lat, "Latency of all requests per window");
  for (double d = d_lo; d <= d_hi + 1e-9; d += 1) {
    for (int m : {1, 2, 5}) {
      const double v = m * std::pow(10.0, d);
      if (std::log10(v) > d_hi + 1e-9) break;
      absl::StrAppendFormat(&svg, R"(<line x1="%.1f" y1="%.1f" x2="%.1f" y2="%.1f" stroke="%s"/>)",
                            lat.left, lat_y(v), lat.left + lat.width, lat_y(v),
                            m == 1 ? "#ccc" : "#eee");
      absl::StrAppendFormat(&svg,
                            R"(<text x="%.1f" y="%.1f" text-anchor="end">%g</text>)"
                            "\n",
                            lat.left - 6, lat_y(v) + 4, v);
    }
  }
  XAxis(svg, lat);
  YLabel(svg, lat, "latency (ms, log scale)");
  WarmupLine(svg, lat, warmup_end);
  Polyline(svg, lat, windows, "#d62728",
           [&](const Window& w) { return w.requests ? lat_y(w.p99_ms) : NAN; });
  Polyline(svg, lat, windows, "#1f77b4",
           [&](const Window& w) { return w.requests ? lat_y(w.p50_ms) : NAN; });
  Legend(svg, lat, 0, "#d62728", "p99");
  Legend(svg, lat, 1, "#1f77b4", "p50");

  // Resident memory, linear from 0.
  const Panel mem{90, 410, width - 130, 230, x_max};
  double rss_max = static_cast<double>(rss_warm_kib) * (1 + max_growth_percent / 100);
  for (const Window& w : windows) rss_max = std::max(rss_max, static_cast<double>(w.rss_kib));
  rss_max /= 1024;
  const double step = NiceStep(std::max(rss_max, 1.0), 5);
  const double top_mib = std::ceil(rss_max * 1.1 / step) * step;
  auto mem_y = [&](double mib) { return mem.top + mem.height * (1 - mib / top_mib); };
  Frame(svg, mem, "Resident memory of shapeid-server (VmRSS) at each window's end");
  for (double v = 0; v <= top_mib + 1e-9; v += step) {
    absl::StrAppendFormat(&svg,
                          R"(<line x1="%.1f" y1="%.1f" x2="%.1f" y2="%.1f" stroke="#ddd"/>)"
                          R"(<text x="%.1f" y="%.1f" text-anchor="end">%g</text>)"
                          "\n",
                          mem.left, mem_y(v), mem.left + mem.width, mem_y(v), mem.left - 6,
                          mem_y(v) + 4, v);
  }
  if (rss_warm_kib > 0) {
    const double base = rss_warm_kib / 1024.0;
    const double limit = base * (1 + max_growth_percent / 100);
    absl::StrAppendFormat(&svg,
                          R"(<rect x="%.1f" y="%.1f" width="%.1f" height="%.1f" )"
                          R"(fill="#2ca02c" fill-opacity="0.12"/>)"
                          R"(<text x="%.1f" y="%.1f" fill="#2a7a2a">pass band: up to +%g %% )"
                          R"(over %.1f MiB (after warm-up)</text>)"
                          "\n",
                          mem.X(warmup_end), mem_y(limit), mem.X(x_max) - mem.X(warmup_end),
                          std::max(1.0, mem_y(base) - mem_y(limit)), mem.X(warmup_end) + 4,
                          mem_y(limit) - 4, max_growth_percent, base);
  }
  XAxis(svg, mem);
  YLabel(svg, mem, "server RSS (MiB)");
  WarmupLine(svg, mem, warmup_end);
  Polyline(
      svg, mem, windows, "#2ca02c",
      [&](const Window& w) { return w.rss_kib ? mem_y(w.rss_kib / 1024.0) : NAN; },
      rss_start_kib > 0 ? absl::StrFormat("%.1f,%.1f ", mem.X(0), mem_y(rss_start_kib / 1024.0))
                        : "");
  svg += "</svg>\n";
  return svg;
}

}  // namespace shapeid::soak
