// See heatmap_svg.hpp. The PNG is written by hand (signature, IHDR, one IDAT compressed by
// zlib, IEND, each chunk with its CRC-32) so no imaging library is needed; the colour scale is a
// five-stop ramp from dark blue through green to red.
#include "app/heatmap_svg.hpp"

#include <zlib.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>

#include "core/number_text.hpp"

namespace ncd::app {
namespace {

void put_u32(std::string& out, std::uint32_t v) {
  for (int s = 24; s >= 0; s -= 8) out.push_back(static_cast<char>((v >> s) & 0xffu));
}

void chunk(std::string& out, const char* type, const std::string& data) {
  put_u32(out, static_cast<std::uint32_t>(data.size()));
  std::string body(type, 4);
  body += data;
  out += body;
  const auto crc =
      crc32(0L, reinterpret_cast<const Bytef*>(body.data()), static_cast<uInt>(body.size()));
  put_u32(out, static_cast<std::uint32_t>(crc));
}

std::string base64(const std::string& in) {
  static constexpr char k[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((in.size() + 2) / 3 * 4);
  std::size_t i = 0;
  for (; i + 2 < in.size(); i += 3) {
    const std::uint32_t v = (std::uint32_t{static_cast<std::uint8_t>(in[i])} << 16) |
                            (std::uint32_t{static_cast<std::uint8_t>(in[i + 1])} << 8) |
                            std::uint32_t{static_cast<std::uint8_t>(in[i + 2])};
    for (int s = 18; s >= 0; s -= 6) out.push_back(k[(v >> s) & 63u]);
  }
  if (i < in.size()) {
    std::uint32_t v = static_cast<std::uint32_t>(static_cast<std::uint8_t>(in[i])) << 16;
    if (i + 1 < in.size())
      v |= static_cast<std::uint32_t>(static_cast<std::uint8_t>(in[i + 1])) << 8;
    out.push_back(k[(v >> 18) & 63u]);
    out.push_back(k[(v >> 12) & 63u]);
    out.push_back(i + 1 < in.size() ? k[(v >> 6) & 63u] : '=');
    out.push_back('=');
  }
  return out;
}

std::array<std::uint8_t, 3> ramp(double u) {
  static constexpr double stops[5][3] = {
      {40, 30, 100}, {30, 110, 180}, {40, 175, 120}, {235, 200, 40}, {180, 25, 40}};
  u = std::clamp(u, 0.0, 1.0) * 4.0;
  const int k = std::min(3, static_cast<int>(u));
  const double f = u - k;
  std::array<std::uint8_t, 3> c{};
  for (int ch = 0; ch < 3; ++ch) {
    c[static_cast<std::size_t>(ch)] = static_cast<std::uint8_t>(
        std::lround(stops[k][ch] + f * (stops[k + 1][ch] - stops[k][ch])));
  }
  return c;
}

std::string esc(const std::string& s) {
  std::string out;
  for (const char c : s) {
    if (c == '<')
      out += "&lt;";
    else if (c == '>')
      out += "&gt;";
    else if (c == '&')
      out += "&amp;";
    else
      out += c;
  }
  return out;
}

double tick_step(double span) {
  const double raw = span / 5.0;
  const double p = std::pow(10.0, std::floor(std::log10(raw)));
  for (const double m : {1.0, 2.0, 5.0}) {
    if (m * p >= raw) return m * p;
  }
  return 10.0 * p;
}

}  // namespace

std::string encode_png_rgb(int width, int height, const std::vector<std::uint8_t>& rgb) {
  if (width <= 0 || height <= 0 ||
      rgb.size() != static_cast<std::size_t>(width) * static_cast<std::size_t>(height) * 3) {
    throw std::runtime_error("encode_png_rgb: the pixels do not match the size");
  }
  std::string raw;
  const auto row = static_cast<std::size_t>(width) * 3;
  raw.reserve((row + 1) * static_cast<std::size_t>(height));
  for (int y = 0; y < height; ++y) {
    raw.push_back('\0');  // filter: none
    raw.append(reinterpret_cast<const char*>(rgb.data()) + static_cast<std::size_t>(y) * row, row);
  }
  uLongf size = compressBound(static_cast<uLong>(raw.size()));
  std::string z(size, '\0');
  if (compress2(reinterpret_cast<Bytef*>(z.data()), &size,
                reinterpret_cast<const Bytef*>(raw.data()), static_cast<uLong>(raw.size()),
                6) != Z_OK) {
    throw std::runtime_error("encode_png_rgb: zlib failed");
  }
  z.resize(size);
  std::string png("\x89PNG\r\n\x1a\n", 8);
  std::string ihdr;
  put_u32(ihdr, static_cast<std::uint32_t>(width));
  put_u32(ihdr, static_cast<std::uint32_t>(height));
  ihdr += std::string("\x08\x02\x00\x00\x00", 5);  // 8 bits, RGB, deflate, no filter, no interlace
  chunk(png, "IHDR", ihdr);
  chunk(png, "IDAT", z);
  chunk(png, "IEND", "");
  return png;
}

namespace {

// The colour scale's range: the finite values' (0..1 when there are none), at least 1e-12 wide.
struct ValueRange {
  double lo = 0.0, hi = 1.0;
};

ValueRange value_range(const std::vector<double>& values) {
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (const double v : values) {
    if (std::isfinite(v)) {
      lo = std::min(lo, v);
      hi = std::max(hi, v);
    }
  }
  if (!std::isfinite(lo)) lo = 0.0, hi = 1.0;
  if (hi - lo < 1e-12) hi = lo + 1.0;
  return {lo, hi};
}

// The picture as PNG: at most max_image_px a side, sampling the nearest cell; cells without a
// value grey.
std::string heatmap_png(const HeatMap& m, double lo, double hi) {
  const int step = std::max(1, (std::max(m.nx, m.ny) + m.max_image_px - 1) / m.max_image_px);
  const int w = (m.nx + step - 1) / step, h = (m.ny + step - 1) / step;
  std::vector<std::uint8_t> rgb(static_cast<std::size_t>(w) * static_cast<std::size_t>(h) * 3);
  for (int py = 0; py < h; ++py) {
    const int j = std::min(m.ny - 1, (h - 1 - py) * step);  // top row of the image: y_max
    for (int px = 0; px < w; ++px) {
      const int i = std::min(m.nx - 1, px * step);
      const double v = m.values[static_cast<std::size_t>(j) * static_cast<std::size_t>(m.nx) +
                                static_cast<std::size_t>(i)];
      const auto c = std::isfinite(v) ? ramp((v - lo) / (hi - lo))
                                      : std::array<std::uint8_t, 3>{160, 160, 160};
      const auto o = (static_cast<std::size_t>(py) * static_cast<std::size_t>(w) +
                      static_cast<std::size_t>(px)) *
                     3;
      rgb[o] = c[0];
      rgb[o + 1] = c[1];
      rgb[o + 2] = c[2];
    }
  }
  return encode_png_rgb(w, h, rgb);
}

}  // namespace

std::string render_heatmap_svg(const HeatMap& m) {
  if (m.nx <= 0 || m.ny <= 0 ||
      m.values.size() != static_cast<std::size_t>(m.nx) * static_cast<std::size_t>(m.ny)) {
    throw std::runtime_error("render_heatmap_svg: the values do not match the size");
  }
  const ValueRange range = value_range(m.values);
  const double lo = range.lo, hi = range.hi;
  // Plot area keeps the patch's aspect ratio within 760 × 520 px.
  const double ax = m.x_max_mm - m.x_min_mm, ay = m.y_max_mm - m.y_min_mm;
  const double scale = std::min(760.0 / ax, 520.0 / ay);
  const double pw = ax * scale, ph = ay * scale;
  const double left = 80, top = 60 + 16.0 * static_cast<double>(m.notes.size());
  const double width = left + pw + 150, height = top + ph + 60;
  std::string s;
  s += "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" + text::sig(width, 4) + "\" height=\"" +
       text::sig(height, 4) + "\" font-family=\"sans-serif\" font-size=\"12\">\n";
  s += "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
  s += "<text x=\"" + text::sig(left, 4) + "\" y=\"24\" font-size=\"15\">" + esc(m.title) +
       "</text>\n";
  for (std::size_t k = 0; k < m.notes.size(); ++k) {
    s += "<text x=\"" + text::sig(left, 4) + "\" y=\"" +
         text::sig(44 + 16.0 * static_cast<double>(k), 4) + "\" fill=\"#444\">" + esc(m.notes[k]) +
         "</text>\n";
  }
  s += "<image x=\"" + text::sig(left, 4) + "\" y=\"" + text::sig(top, 4) + "\" width=\"" +
       text::sig(pw, 4) + "\" height=\"" + text::sig(ph, 4) +
       "\" preserveAspectRatio=\"none\" style=\"image-rendering:pixelated\" "
       "href=\"data:image/png;base64," +
       base64(heatmap_png(m, lo, hi)) + "\"/>\n";
  s += "<rect x=\"" + text::sig(left, 4) + "\" y=\"" + text::sig(top, 4) + "\" width=\"" +
       text::sig(pw, 4) + "\" height=\"" + text::sig(ph, 4) +
       "\" fill=\"none\" stroke=\"black\"/>\n";
  const double sx = tick_step(ax), sy = tick_step(ay);
  for (double t = std::ceil(m.x_min_mm / sx) * sx; t <= m.x_max_mm + 1e-9 * ax; t += sx) {
    const double x = left + (t - m.x_min_mm) * scale;
    s += "<line x1=\"" + text::sig(x, 4) + "\" y1=\"" + text::sig(top + ph, 4) + "\" x2=\"" +
         text::sig(x, 4) + "\" y2=\"" + text::sig(top + ph + 5, 4) +
         "\" stroke=\"black\"/><text x=\"" + text::sig(x, 4) + "\" y=\"" +
         text::sig(top + ph + 18, 4) + "\" text-anchor=\"middle\">" + text::tick(t, sx, 4) +
         "</text>\n";
  }
  for (double t = std::ceil(m.y_min_mm / sy) * sy; t <= m.y_max_mm + 1e-9 * ay; t += sy) {
    const double y = top + ph - (t - m.y_min_mm) * scale;
    s += "<line x1=\"" + text::sig(left - 5, 4) + "\" y1=\"" + text::sig(y, 4) + "\" x2=\"" +
         text::sig(left, 4) + "\" y2=\"" + text::sig(y, 4) + "\" stroke=\"black\"/><text x=\"" +
         text::sig(left - 8, 4) + "\" y=\"" + text::sig(y + 4, 4) + "\" text-anchor=\"end\">" +
         text::tick(t, sy, 4) + "</text>\n";
  }
  s += "<text x=\"" + text::sig(left + pw / 2, 4) + "\" y=\"" + text::sig(top + ph + 40, 4) +
       "\" text-anchor=\"middle\">" + esc(m.x_label) + "</text>\n";
  s += "<text transform=\"translate(" + text::sig(left - 55, 4) + "," + text::sig(top + ph / 2, 4) +
       ") rotate(-90)\" text-anchor=\"middle\">" + esc(m.y_label) + "</text>\n";
  // Colour scale.
  const double bx = left + pw + 30, bh = std::min(ph, 300.0);
  for (int k = 0; k < 64; ++k) {
    const auto c = ramp((k + 0.5) / 64.0);
    char col[16];
    std::snprintf(col, sizeof col, "#%02x%02x%02x", c[0], c[1], c[2]);
    s += "<rect x=\"" + text::sig(bx, 4) + "\" y=\"" +
         text::sig(top + bh - (k + 1) * bh / 64.0, 4) + "\" width=\"18\" height=\"" +
         text::sig(bh / 64.0 + 0.5, 4) + "\" fill=\"" + col + "\"/>\n";
  }
  s += "<rect x=\"" + text::sig(bx, 4) + "\" y=\"" + text::sig(top, 4) +
       "\" width=\"18\" height=\"" + text::sig(bh, 4) + "\" fill=\"none\" stroke=\"black\"/>\n";
  const double sv = tick_step(hi - lo);
  for (double t = std::ceil(lo / sv) * sv; t <= hi + 1e-9 * (hi - lo); t += sv) {
    const double y = top + bh - (t - lo) / (hi - lo) * bh;
    s += "<text x=\"" + text::sig(bx + 24, 4) + "\" y=\"" + text::sig(y + 4, 4) + "\">" +
         text::tick(t, sv, 4) + "</text>\n";
  }
  s += "<text x=\"" + text::sig(bx, 4) + "\" y=\"" + text::sig(top + bh + 20, 4) + "\">" +
       esc(m.value_label) + "</text>\n";
  s += "</svg>\n";
  return s;
}

}  // namespace ncd::app
