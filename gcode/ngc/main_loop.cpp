// The RS-274/NGC interpreter: the main loop: lines, O-word control flow, calls and returns. The
// reading and execution order is in interpreter.cpp.
#include "gcode/ngc/interp.hpp"

namespace ncd::toolpath::ngc {

void Interpreter::execute_all() {
  frames_.push_back(Frame{});
  cur_file_ = 0;
  cur_line_ = 0;
  bool first_content = true;
  std::string comment;
  while (!ended_) {
    const auto& lines = files_[cur_file_]->lines;
    if (cur_line_ >= lines.size()) {
      if (frames_.size() > 1) {
        fail("end of file inside subroutine o" + frames_.back().sub + "; add its endsub");
      }
      if (!frames_.back().loops.empty()) {
        const auto& [label, loop] = *frames_.back().loops.begin();
        cur_line_ = loop.start;
        fail("the loop o" + label +
             " opened here is not closed before the end of the file; "
             "add its end (endwhile, while or endrepeat)");
      }
      if (opened_by_percent_) {
        cur_line_ = lines.empty() ? 0 : lines.size() - 1;
        fail("the program opens with % but has neither a closing % line nor M2/M30; add one");
      }
      break;  // a program that just ends: treated as ended (LinuxCNC wants M2 or %)
    }
    if (++blocks_ > opt_.max_blocks) {
      fail("the program ran " + std::to_string(opt_.max_blocks) +
           " blocks without ending; a loop that never ends? check its condition");
    }
    const std::size_t this_line = cur_line_;
    bool has_comment = false;
    normalise(lines[cur_line_], norm_, &comment, &has_comment);
    next_line_ = cur_line_ + 1;
    if (norm_ == "%") {
      if (cur_file_ == 0 && first_content && frames_.size() == 1) {
        first_content = false;
        opened_by_percent_ = true;
        cur_line_ = next_line_;
        continue;
      }
      break;  // closing %: the end
    }
    if (!norm_.empty() || has_comment) first_content = false;
    execute_line(has_comment ? &comment : nullptr);
    (void)this_line;
    cur_line_ = next_line_;
  }
}

void Interpreter::execute_line(const std::string* comment) {
  const std::string& s = norm_;
  std::size_t i = 0;
  if (i < s.size() && s[i] == '/') {
    if (opt_.block_delete) return;
    ++i;
  }
  if (i < s.size() && s[i] == 'n') {
    ++i;
    const std::size_t b = i;
    while (i < s.size() && (std::isdigit(static_cast<unsigned char>(s[i])) || s[i] == '.')) ++i;
    if (i == b) fail("N without a line number; write N10 or remove it");
  }
  if (i < s.size() && s[i] == 'o') {
    OLine o;
    parse_oline(s, o);
    execute_oword(o);
    return;
  }
  if (skipping_sub_) return;
  Block b;
  read_block(s, i, b);
  if (comment && comment_is(*comment, "msg,")) {
    b.has_message = true;
    b.message = comment->substr(comment->find(',') + 1);
  } else if (comment && comment_is(*comment, "debug,") && params_[5599] > 0.0) {
    b.has_message = true;
    b.message = expand_debug(comment->substr(comment->find(',') + 1));
  }
  if (b.ng == 0 && b.nm == 0 && b.mask == 0 && !b.has_polar() && !b.has_message) return;
  execute_block(b);
}

bool Interpreter::comment_is(const std::string& c, const std::string& tag) {
  std::size_t i = 0;
  while (i < c.size() && std::isspace(static_cast<unsigned char>(c[i]))) ++i;
  if (c.size() < i + tag.size()) return false;
  for (std::size_t k = 0; k < tag.size(); ++k) {
    if (std::tolower(static_cast<unsigned char>(c[i + k])) != tag[k]) return false;
  }
  return true;
}

// (DEBUG, text): #n and #<name> replaced by their values in the format of the last %d, %f
// or %.Nf (LinuxCNC's convert_param_comment; default six decimals), ###### when undefined.
std::string Interpreter::expand_debug(const std::string& text) const {
  std::string out;
  int decimals = 6;
  for (std::size_t i = 0; i < text.size();) {
    const char c = text[i];
    if (c == '%') {
      if (i + 1 < text.size() && text[i + 1] == 'd') {
        decimals = 0;
        i += 2;
      } else if (i + 1 < text.size() && text[i + 1] == 'f') {
        decimals = 4;
        i += 2;
      } else if (i + 3 < text.size() && text[i + 1] == '.' &&
                 std::isdigit(static_cast<unsigned char>(text[i + 2])) && text[i + 3] == 'f') {
        decimals = text[i + 2] - '0';
        i += 4;
      } else {
        out.push_back('%');
        ++i;
      }
      continue;
    }
    if (c != '#') {
      out.push_back(c);
      ++i;
      continue;
    }
    ++i;
    bool found = false;
    double value = 0.0;
    if (i < text.size() && std::isdigit(static_cast<unsigned char>(text[i]))) {
      long n = 0;
      while (i < text.size() && std::isdigit(static_cast<unsigned char>(text[i]))) {
        n = std::min(n * 10 + (text[i] - '0'), 100000L);
        ++i;
      }
      if (n >= 0 && n <= kMaxParam) {
        value = params_[static_cast<std::size_t>(n)];
        found = true;
      }
    } else if (i < text.size() && text[i] == '<') {
      std::string name;
      ++i;
      while (i < text.size() && text[i] != '>') {
        if (!std::isspace(static_cast<unsigned char>(text[i]))) {
          name.push_back(static_cast<char>(std::tolower(static_cast<unsigned char>(text[i]))));
        }
        ++i;
      }
      if (i >= text.size()) fail("named parameter in a DEBUG comment without '>'; close it");
      ++i;
      if (!name.empty() && name[0] == '_') {
        const auto it = globals_.find(name);
        if (it != globals_.end()) {
          value = it->second;
          found = true;
        } else {
          found = predefined(name, &value);
          if (!found) {
            fail("#<" + name +
                 "> in a DEBUG comment is not defined (not one of LinuxCNC's predefined "
                 "parameters ncd knows: docs/ngc-interpreter.md): remove it");
          }
        }
      } else {
        const auto& locals = frames_.back().locals;
        const auto it = locals.find(name);
        if (it != locals.end()) {
          value = it->second;
          found = true;
        }
      }
    } else {
      out.push_back('#');
      continue;
    }
    if (found) {
      char buf[64];
      const int n = std::snprintf(buf, sizeof buf, "%.*f", decimals,
                                  std::abs(value) < kTolEqual ? 0.0 : value);
      out += n > 0 && n < static_cast<int>(sizeof buf) ? std::string(buf) : "######";
    } else {
      out += "######";
    }
  }
  return out;
}

bool Interpreter::condition(const OLine& o) {
  std::size_t i = o.args_at;
  if (i >= norm_.size() || norm_[i] != '[')
    fail("o" + o.label + " " + o.keyword + " needs a condition [..]");
  return read_expression(norm_, i) != 0.0;
}

// An O-word line met in the flow of the program: subroutines, branches and loops (LinuxCNC's
// interp_o_word.cc). Each keyword's work is a function below.
void Interpreter::execute_oword(const OLine& o) {
  const std::string& k = o.keyword;
  Frame& fr = frames_.back();
  std::string found;
  if (k == "sub") {
    // Definition met in the flow: skip its body.
    const std::size_t end = seek(o.label, {"endsub"}, found);
    next_line_ = end + 1;
  } else if (k == "endsub" || k == "return") {
    o_return(o);
  } else if (k == "call") {
    o_call(o);
  } else if (k == "if") {
    if (!condition(o)) branch_skip(o.label);
  } else if (k == "elseif" || k == "else") {
    // Reached in the flow: the branch before was taken.
    next_line_ = seek(o.label, {"endif"}, found) + 1;
  } else if (k == "endif") {
  } else if (k == "do") {
    fr.loops[o.label] = Loop{Loop::do_loop, cur_line_, 0};
  } else if (k == "while") {
    o_while(o);
  } else if (k == "endwhile") {
    const auto it = fr.loops.find(o.label);
    if (it == fr.loops.end()) fail("o" + o.label + " endwhile without its while; add it");
    next_line_ = it->second.start;
  } else if (k == "repeat") {
    o_repeat(o);
  } else if (k == "endrepeat") {
    o_endrepeat(o);
  } else if (k == "break" || k == "continue") {
    o_break_or_continue(o);
  } else {
    fail("unknown O-word keyword '" + k +
         "'; use sub endsub call return if elseif else endif "
         "while endwhile do repeat endrepeat break continue");
  }
}

// endsub, return [value]: back to the caller, its parameters #1-#30 restored.
void Interpreter::o_return(const OLine& o) {
  const std::string& k = o.keyword;
  Frame& fr = frames_.back();
  if (frames_.size() == 1) fail("o" + o.label + " " + k + " outside a subroutine; remove it");
  std::size_t i = o.args_at;
  double returned = 0.0;
  value_returned_ = false;
  if (i < norm_.size() && norm_[i] == '[') {
    returned = read_expression(norm_, i);
    value_returned_ = true;
  }
  value_ = returned;
  if (fr.m73) restore_modes(*fr.m73, "M73");  // the caller's modes back (LinuxCNC's M73)
  for (std::size_t p = 0; p < 30; ++p) params_[p + 1] = fr.saved[p];
  const std::size_t ret_file = fr.file, ret_line = fr.return_line;
  frames_.pop_back();
  cur_file_ = ret_file;
  next_line_ = ret_line;
}

// call [args]: a new frame with #1-#30 set to the arguments.
void Interpreter::o_call(const OLine& o) {
  std::array<double, 30> args{};
  std::size_t i = o.args_at;
  std::size_t n = 0;
  while (i < norm_.size() && norm_[i] == '[') {
    if (n >= 30) fail("more than 30 arguments to o" + o.label + " call");
    args[n++] = read_expression(norm_, i);
  }
  if (i != norm_.size())
    fail("unexpected '" + norm_.substr(i) + "' after o" + o.label + " call arguments");
  auto it = subs_.find(o.label);
  if (it == subs_.end()) it = load_sub_file(o.label);
  if (frames_.size() > kMaxCallDepth) {
    fail("subroutine calls nested deeper than " + std::to_string(kMaxCallDepth) +
         "; a recursion that never ends?");
  }
  Frame nf;
  nf.file = cur_file_;
  nf.return_line = next_line_;
  nf.sub = o.label;
  for (std::size_t p = 0; p < 30; ++p) {
    nf.saved[p] = params_[p + 1];
    params_[p + 1] = args[p];
  }
  frames_.push_back(std::move(nf));
  cur_file_ = it->second.first;
  next_line_ = it->second.second + 1;
}

// while [cond]: the end of a do loop, or the head of a while loop.
void Interpreter::o_while(const OLine& o) {
  Frame& fr = frames_.back();
  std::string found;
  const auto it = fr.loops.find(o.label);
  if (it != fr.loops.end() && it->second.kind == Loop::do_loop) {
    if (condition(o)) {
      next_line_ = it->second.start + 1;
    } else {
      fr.loops.erase(it);
    }
  } else if (condition(o)) {
    fr.loops[o.label] = Loop{Loop::while_loop, cur_line_, 0};
  } else {
    fr.loops.erase(o.label);
    next_line_ = seek(o.label, {"endwhile"}, found) + 1;
  }
}

// repeat [n]
void Interpreter::o_repeat(const OLine& o) {
  Frame& fr = frames_.back();
  std::string found;
  std::size_t i = o.args_at;
  if (i >= norm_.size() || norm_[i] != '[') fail("o" + o.label + " repeat needs a count [n]");
  const double n = read_expression(norm_, i);
  if (n > 1e9) fail("repeat count " + text::sig(n) + " is absurd; at most 1e9");
  const long count = static_cast<long>(std::round(n));
  if (count <= 0) {
    next_line_ = seek(o.label, {"endrepeat"}, found) + 1;
  } else {
    fr.loops[o.label] = Loop{Loop::repeat_loop, cur_line_, count};
  }
}

void Interpreter::o_endrepeat(const OLine& o) {
  Frame& fr = frames_.back();
  const auto it = fr.loops.find(o.label);
  if (it == fr.loops.end()) fail("o" + o.label + " endrepeat without its repeat; add it");
  if (--it->second.remaining > 0) {
    next_line_ = it->second.start + 1;
  } else {
    fr.loops.erase(it);
  }
}

// break, continue: out of the loop, or to its next turn.
void Interpreter::o_break_or_continue(const OLine& o) {
  const std::string& k = o.keyword;
  Frame& fr = frames_.back();
  std::string found;
  const auto it = fr.loops.find(o.label);
  if (it == fr.loops.end()) fail("o" + o.label + " " + k + " outside its loop");
  const Loop loop = it->second;
  if (loop.kind == Loop::do_loop && k == "continue") {
    fail("o" + o.label +
         " continue inside a do loop: LinuxCNC leaves the loop there, "
         "which is rarely meant; use a while loop");
  }
  if (loop.kind == Loop::repeat_loop) {
    fail("o" + o.label + " " + k + " inside a repeat loop: LinuxCNC allows " + k +
         " only in while and do loops; use a while loop with a counter");
  }
  const std::size_t end = loop.kind == Loop::while_loop ? seek(o.label, {"endwhile"}, found)
                          : loop.kind == Loop::do_loop  ? seek(o.label, {"while"}, found)
                                                        : seek(o.label, {"endrepeat"}, found);
  if (k == "break") {
    fr.loops.erase(o.label);
    next_line_ = end + 1;
  } else {
    next_line_ = loop.kind == Loop::while_loop ? loop.start : end;
  }
}

// A false if/elseif: on to the next elseif (evaluated), else or endif of the label.
void Interpreter::branch_skip(const std::string& label) {
  std::string found;
  for (;;) {
    const std::size_t at = seek(label, {"elseif", "else", "endif"}, found);
    if (found != "elseif") {
      next_line_ = at + 1;
      return;
    }
    cur_line_ = at;
    normalise(files_[cur_file_]->lines[at], norm_, nullptr, nullptr);
    OLine o;
    parse_oline(norm_, o);
    if (condition(o)) {
      next_line_ = at + 1;
      return;
    }
  }
}

std::unordered_map<std::string, std::pair<std::size_t, std::size_t>>::iterator
Interpreter::load_sub_file(const std::string& label) {
  for (const std::string& dir : opt_.subroutine_path) {
    const std::string path = (std::filesystem::path(dir) / (label + ".ngc")).string();
    std::ifstream in(path, std::ios::binary);
    if (!in) continue;
    std::ostringstream t;
    t << in.rdbuf();
    files_.push_back(std::make_unique<SourceFile>());
    SourceFile& f = *files_.back();
    f.name = path;
    f.text = t.str();
    split_lines(f);
    program_.files.push_back(path);
    scan_subs(files_.size() - 1);
    const auto it = subs_.find(label);
    if (it != subs_.end()) return it;
    fail(path + " has no o<" + label + "> sub; define it there");
  }
  fail("subroutine o" + label + " is not defined in the file nor found as " + label +
       ".ngc on the subroutine path; define it or set [program] subroutine_path");
}

}  // namespace ncd::toolpath::ngc
