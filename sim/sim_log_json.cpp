// The simulated controller's log as JSON (`ncd sim-controller --log`, the tests): its settings,
// counts, and each record (moves, blocks executed, events, alarms, errors, resets, link events).
#include "sim/sim_controller.hpp"

namespace ncd::comms {

using Json = nlohmann::json;

namespace {

Json optional_json(const std::optional<long>& v) {
  return v ? Json(*v) : Json(nullptr);
}

// The moves executed, each with its end point, feed, G code, N and time; an index of the
// rotary axis with its axis and angle too.
Json moves_json(const SimLog& l) {
  Json moves = Json::array();
  for (const SimMove& m : l.moves) {
    moves.push_back({{"p", {m.p[0], m.p[1], m.p[2]}},
                     {"feed_mm_per_min", m.feed_mm_per_min},
                     {"g", m.g},
                     {"n", optional_json(m.n)},
                     {"t_s", m.t_s},
                     {"seq", m.seq}});
    if (m.rotary_deg) {  // an index: the axis and the angle it ended at (feed: deg/min)
      moves.back()["rotary_axis"] = std::string(1, m.rotary_axis);
      moves.back()["rotary_deg"] = *m.rotary_deg;
    }
  }
  return moves;
}

// The underruns: when each dry spell began, after which block, and how long.
Json underruns_json(const SimLog& l) {
  Json underruns = Json::array();
  for (const SimUnderrun& u : l.underrun_events) {
    underruns.push_back(
        {{"t_s", u.t_s}, {"block", u.block}, {"n", optional_json(u.n)}, {"dwell_s", u.dwell_s}});
  }
  return underruns;
}

// The alarms raised.
Json alarms_json(const SimLog& l) {
  Json alarms = Json::array();
  for (const SimAlarm& a : l.alarms) {
    alarms.push_back({{"t_s", a.t_s},
                      {"code", a.code},
                      {"block", a.block},
                      {"n", optional_json(a.n)},
                      {"detail", a.detail}});
  }
  return alarms;
}

// The error replies (ack).
Json errors_json(const SimLog& l) {
  Json errors = Json::array();
  for (const SimErrorReply& e : l.errors) {
    errors.push_back({{"t_s", e.t_s},
                      {"line", e.line},
                      {"code", e.code},
                      {"text", e.text},
                      {"message", e.message}});
  }
  return errors;
}

// The blocks executed to their end, in order.
Json executed_json(const SimLog& l) {
  Json executed = Json::array();
  for (const SimExecuted& e : l.executed) {
    executed.push_back(
        {{"seq", e.seq}, {"n", optional_json(e.n)}, {"text", e.text}, {"t_s", e.t_s}});
  }
  return executed;
}

// The events executed (spindle, coolant, tool, dwell, stops, the end, holds).
Json events_json(const SimLog& l) {
  Json events = Json::array();
  for (const SimEvent& e : l.events) {
    events.push_back({{"t_s", e.t_s},
                      {"seq", e.seq},
                      {"n", optional_json(e.n)},
                      {"kind", e.kind},
                      {"value", e.value}});
  }
  return events;
}

// The controller resets.
Json resets_json(const SimLog& l) {
  Json resets = Json::array();
  for (const SimReset& r : l.resets) {
    resets.push_back({{"t_s", r.t_s},
                      {"cause", r.cause},
                      {"in_motion", r.in_motion},
                      {"aborted", r.aborted ? Json(*r.aborted) : Json(nullptr)},
                      {"position", {r.position[0], r.position[1], r.position[2]}},
                      {"blocks_lost", r.blocks_lost},
                      {"executed_at_last_report", optional_json(r.executed_at_last_report)}});
  }
  return resets;
}

// The link events (created, senders connected and gone, down, up).
Json link_events_json(const SimLog& l) {
  Json links = Json::array();
  for (const SimLinkEvent& e : l.link_events) {
    links.push_back({{"t_s", e.t_s}, {"event", e.event}, {"device", e.device}});
  }
  return links;
}

}  // namespace

Json settings_json(const SimControllerConfig& c) {
  const SimFaults& f = c.faults;
  return Json{{"link", c.line.device},
              {"baud", c.line.baud},
              {"frame", frame_text(c.line)},
              {"bits_per_char", bits_per_char(c.line)},
              {"chars_per_s", chars_per_s(c.line)},
              {"flow", to_string(c.line.flow)},
              {"protocol", to_string(c.line.protocol)},
              {"eob", c.line.eob == EndOfBlock::CrLf ? "crlf" : "lf"},
              {"buffer_bytes", c.buffer_bytes},
              {"xoff_at", c.xoff_at.value_or(0)},
              {"xon_at", c.xon_at.value_or(0)},
              {"max_block_chars", max_block_chars(c)},
              {"planner_blocks", c.planner_blocks},
              {"rapid_mm_per_min", c.rapid_mm_per_min},
              {"prime_idle_s", c.prime_idle_s},
              {"underrun_grace_s", c.underrun_grace_s},
              {"exit_at_end", c.exit_at_end},
              {"seed", c.seed},
              {"skip_duplicate_n", c.skip_duplicate_n},
              {"reset_on_open", c.reset_on_open},
              {"boot_s", c.boot_s},
              {"report_line_numbers", c.report_line_numbers},
              {"status_mask", c.status_mask},
              {"hold_accel_mm_per_s2", c.hold_accel_mm_per_s2},
              {"dialect", c.dialect ? Json(to_string(*c.dialect)) : Json(nullptr)},
              {"machine_safety", c.machine_safety},
              {"tool_change_s", c.tool_change_s},
              {"optional_stop", c.optional_stop},
              {"clock", c.clock ? "injected" : "wall"},
              {"faults",
               {{"drop_link_after_blocks", f.drop_link_after_blocks},
                {"drop_link_after_chars", f.drop_link_after_chars},
                {"down_s", f.down_s},
                {"xoff_storm", f.xoff_storm},
                {"hold_after_blocks", f.hold_after_blocks},
                {"hold_s", f.hold_s},
                {"noise_bytes_per_s", f.noise_bytes_per_s},
                {"alarm_after_blocks", f.alarm_after_blocks},
                {"reset_after_blocks", f.reset_after_blocks},
                {"restart_after_blocks", f.restart_after_blocks}}}};
}

Json to_json(const SimLog& l) {
  return Json{{"settings", settings_json(l.config)},
              {"stop_reason", l.stop_reason},
              {"duration_s", l.duration_s},
              {"lines_received", l.lines_received},
              {"blocks_received", l.blocks_received},
              {"blocks_executed", l.blocks_executed},
              {"framing_lines", l.framing_lines},
              {"duplicates_discarded", l.duplicates_discarded},
              {"blocks_rejected", l.blocks_rejected},
              {"lines_after_end", l.lines_after_end},
              {"partial_lines_discarded", l.partial_lines_discarded},
              {"program_sha256", l.program_sha256},
              {"program_end_received", l.program_end_received},
              {"program_end_executed", l.program_end_executed},
              {"first_n", optional_json(l.first_n)},
              {"last_n", optional_json(l.last_n)},
              {"bytes_received", l.bytes_received},
              {"nul_received", l.nul_received},
              {"bytes_after_alarm", l.bytes_after_alarm},
              {"first_byte_t_s", l.first_byte_t_s},
              {"last_byte_t_s", l.last_byte_t_s},
              {"reception_s", l.reception_s},
              {"bytes_per_s", l.bytes_per_s},
              {"chars_per_s", chars_per_s(l.config.line)},
              {"link_use", l.link_use},
              {"buffer_bytes", l.config.buffer_bytes},
              {"max_buffer_fill", l.max_buffer_fill},
              {"max_planner_blocks", l.max_planner_blocks},
              {"execution_start_t_s", l.execution_start_t_s},
              {"execution_end_t_s", l.execution_end_t_s},
              {"underruns", l.underruns},
              {"underrun_events", underruns_json(l)},
              {"dwell_s", l.dwell_s},
              {"alarms", alarms_json(l)},
              {"errors", errors_json(l)},
              {"xoff_sent", l.xoff_sent},
              {"xoff_late", l.xoff_late},
              {"xon_sent", l.xon_sent},
              {"xoff_storms", l.xoff_storms},
              {"holds", l.holds},
              {"noise_bytes_sent", l.noise_bytes_sent},
              {"link_drops", l.link_drops},
              {"sender_connects", l.sender_connects},
              {"sender_disconnects", l.sender_disconnects},
              {"link_events", link_events_json(l)},
              {"path_length_mm", l.path_length_mm},
              {"moves", moves_json(l)},
              {"executed", executed_json(l)},
              {"events", events_json(l)},
              {"resets", resets_json(l)},
              {"status_reports", l.status_reports},
              {"feed_holds", l.feed_holds},
              {"cycle_starts", l.cycle_starts},
              {"bytes_before_banner", l.bytes_before_banner},
              {"banners_sent", l.banners_sent},
              {"banners_lost", l.banners_lost},
              {"unlocks", l.unlocks}};
}

}  // namespace ncd::comms
