// Per-move tool use and roughness caps (tool_use.hpp). Tools are told apart by number and kind;
// a tool's length sums its moves' walked arc lengths (the walker's segment starts). A move is a
// segment of the program: the fit of dense runs (docs/planner.md §3d) splits one into several
// walked segments (polyline parts and curves, each a copy of the program segment's data), whose
// periods are merged back into the one move.
#include "motion/tool_use.hpp"

#include <algorithm>
#include <cstdio>
#include <map>
#include <utility>

#include "core/number_text.hpp"
#include "feed/feed_limits.hpp"

namespace ncd::motion {
namespace {

const auto kRoughnessId = static_cast<std::uint8_t>(feed::FeedLimit::Roughness);

}  // namespace

ToolUse::ToolUse(const Job& job) : moves_(job.path().segments.size()) {}

void ToolUse::add(const Setpoint& sp) {
  if (sp.segment >= moves_.size()) return;
  Move& m = moves_[sp.segment];
  ++m.periods;
  m.walked_max_mm_per_s = std::max(m.walked_max_mm_per_s, sp.v_mm_per_s);
  if (sp.limit_id != kRoughnessId) return;
  m.law_min_mm_per_s = m.law_periods == 0 ? sp.feed_limit_mm_per_s
                                          : std::min(m.law_min_mm_per_s, sp.feed_limit_mm_per_s);
  ++m.law_periods;
}

std::size_t ToolUse::capped_moves() const {
  return static_cast<std::size_t>(
      std::count_if(moves_.begin(), moves_.end(), [](const Move& m) { return m.law_periods > 0; }));
}

namespace {

// The walked segments [first, last] of each program segment, in order (the fit's map: a split
// segment's parts are consecutive).
std::vector<std::pair<std::size_t, std::size_t>> program_moves(const Job& job, std::size_t walked) {
  const std::vector<std::size_t>& source = job.fit_report().source_segment;
  std::vector<std::pair<std::size_t, std::size_t>> out;
  for (std::size_t k = 0; k < walked; ++k) {
    const bool same = !out.empty() && k < source.size() && source[k] == source[out.back().first];
    if (same) {
      out.back().second = k;
    } else {
      out.emplace_back(k, k);
    }
  }
  return out;
}

ToolUse::Move merged(const std::vector<ToolUse::Move>& moves, std::size_t first, std::size_t last) {
  ToolUse::Move m;
  for (std::size_t k = first; k <= last; ++k) {
    const ToolUse::Move& p = moves[k];
    m.periods += p.periods;
    m.walked_max_mm_per_s = std::max(m.walked_max_mm_per_s, p.walked_max_mm_per_s);
    if (p.law_periods == 0) continue;
    m.law_min_mm_per_s =
        m.law_periods == 0 ? p.law_min_mm_per_s : std::min(m.law_min_mm_per_s, p.law_min_mm_per_s);
    m.law_periods += p.law_periods;
  }
  return m;
}

}  // namespace

nlohmann::ordered_json ToolUse::to_json(const Job& job) const {
  const auto& segs = job.path().segments;
  struct Sum {
    toolpath::CutterTool tool;
    std::size_t moves = 0, capped = 0;
    double length_mm = 0.0, walked_max = 0.0;
    const feed::CuttingParams* law = nullptr;
  };
  std::map<std::pair<int, int>, Sum> tools;
  nlohmann::ordered_json runs = nlohmann::ordered_json::array();
  nlohmann::ordered_json capped = nlohmann::ordered_json::array();
  std::size_t capped_total = 0;
  for (const auto& [k, last] : program_moves(job, std::min(segs.size(), moves_.size()))) {
    const toolpath::PathSegment& seg = segs[k];
    if (seg.rapid) continue;  // a G0 cuts nothing
    const Move m = merged(moves_, k, last);
    Sum& s = tools[{seg.tool.number, static_cast<int>(seg.tool.kind)}];
    s.tool = seg.tool;
    ++s.moves;
    s.length_mm += job.walker().segment_start_mm(last + 1) - job.walker().segment_start_mm(k);
    s.walked_max = std::max(s.walked_max, m.walked_max_mm_per_s);
    const feed::CuttingParams* law = job.sampler().cutting_of(k);
    if (law) s.law = law;
    const std::string kind = toolpath::to_string(seg.tool.kind);
    if (runs.empty() || runs.back()["tool"] != seg.tool.number || runs.back()["kind"] != kind) {
      runs.push_back({{"tool", seg.tool.number},
                      {"kind", kind},
                      {"first_line", seg.source_line},
                      {"last_line", seg.source_line},
                      {"moves", 0}});
    }
    runs.back()["last_line"] = seg.source_line;
    runs.back()["moves"] = runs.back()["moves"].get<int>() + 1;
    if (m.law_periods == 0) continue;
    ++s.capped;
    if (++capped_total > kListed) continue;
    capped.push_back(
        {{"line", seg.source_line},
         {"tool", seg.tool.number},
         {"kind", kind},
         {"ball_radius_mm", law ? law->ball_radius_mm : 0.0},
         {"teeth", law ? law->teeth : 0},
         {"programmed_feed_mm_per_min",
          seg.feed_mm_per_min ? nlohmann::ordered_json(*seg.feed_mm_per_min) : nullptr},
         {"capped_feed_mm_per_min", m.law_min_mm_per_s * 60.0},
         {"walked_feed_max_mm_per_min", m.walked_max_mm_per_s * 60.0},
         {"periods_capped", m.law_periods},
         {"periods", m.periods}});
  }
  nlohmann::ordered_json list = nlohmann::ordered_json::array();
  for (const auto& [key, s] : tools) {
    nlohmann::ordered_json e = {{"tool", s.tool.number},
                                {"kind", toolpath::to_string(s.tool.kind)},
                                {"roughness_law", s.law != nullptr}};
    if (s.law) {
      e["ball_radius_mm"] = s.law->ball_radius_mm;
      e["teeth"] = s.law->teeth;
    } else {
      e["radius_mm"] = s.tool.radius_mm > 0.0 ? nlohmann::ordered_json(s.tool.radius_mm) : nullptr;
      e["teeth"] = s.tool.teeth > 0 ? nlohmann::ordered_json(s.tool.teeth) : nullptr;
    }
    e["moves"] = s.moves;
    e["moves_capped"] = s.capped;
    e["length_mm"] = s.length_mm;
    e["walked_feed_max_mm_per_min"] = s.walked_max * 60.0;
    list.push_back(std::move(e));
  }
  return {{"tools", std::move(list)},
          {"tool_runs", std::move(runs)},
          {"capped_moves", std::move(capped)},
          {"capped_moves_total", capped_total}};
}

std::string ToolUse::text(const Job& job) const {
  const nlohmann::ordered_json j = to_json(job);
  std::string out;
  char line[256];
  for (const auto& t : j["tools"]) {
    const bool law = t["roughness_law"].get<bool>();
    std::string what;
    if (law) {
      std::snprintf(line, sizeof line, "ball R %.4g mm, %d teeth: capped by the roughness law",
                    t["ball_radius_mm"].get<double>(), t["teeth"].get<int>());
      what = line;
    } else {
      what =
          std::string("not capped: the roughness law models ball ends only") +
          (t["kind"] == "unknown" ? " (no kind stated; kind= in the tool table or [tools.N])" : "");
    }
    std::snprintf(line, sizeof line,
                  "  tool              T%d %s, %zu moves (%zu capped), %.1f mm, "
                  "feed max %.1f mm/min; ",
                  t["tool"].get<int>(), t["kind"].get<std::string>().c_str(),
                  t["moves"].get<std::size_t>(), t["moves_capped"].get<std::size_t>(),
                  t["length_mm"].get<double>(), t["walked_feed_max_mm_per_min"].get<double>());
    out += line + what + "\n";
  }
  std::size_t shown = 0;
  for (const auto& c : j["capped_moves"]) {
    if (shown++ == kShown) break;
    const auto& f = c["programmed_feed_mm_per_min"];
    std::snprintf(line, sizeof line,
                  "  capped            line %d T%d %s: F %s -> %.1f mm/min (roughness law, "
                  "%lld of %lld periods)\n",
                  c["line"].get<int>(), c["tool"].get<int>(), c["kind"].get<std::string>().c_str(),
                  f.is_null() ? "none" : text::sig(f.get<double>()).c_str(),
                  c["capped_feed_mm_per_min"].get<double>(),
                  static_cast<long long>(c["periods_capped"].get<std::int64_t>()),
                  static_cast<long long>(c["periods"].get<std::int64_t>()));
    out += line;
  }
  const auto total = j["capped_moves_total"].get<std::size_t>();
  if (total > kShown) {
    out += "  capped            … " + std::to_string(total - kShown) +
           " more moves (the report's capped_moves)\n";
  }
  return out;
}

}  // namespace ncd::motion
