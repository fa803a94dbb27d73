// The argument guide (the rules are in cli_guide.hpp).
#include "app/cli_guide.hpp"

#include <algorithm>
#include <cctype>
#include <numeric>

namespace ncd::app {
namespace {

// The subcommands registered on `app`, by name.
std::vector<std::string> command_names(const CLI::App& app) {
  std::vector<std::string> names;
  for (const CLI::App* sub : app.get_subcommands([](const CLI::App*) { return true; })) {
    names.push_back(sub->get_name());
  }
  return names;
}

const CLI::App* find_command(const CLI::App& app, const std::string& name) {
  for (const CLI::App* sub : app.get_subcommands([](const CLI::App*) { return true; })) {
    if (sub->get_name() == name) return sub;
  }
  return nullptr;
}

// Every flag of `cmd` as typed: --long and -s.
std::vector<std::string> flag_names(const CLI::App& cmd) {
  std::vector<std::string> names;
  for (const CLI::Option* o : cmd.get_options({})) {
    for (const std::string& l : o->get_lnames()) names.push_back("--" + l);
    for (const std::string& s : o->get_snames()) names.push_back("-" + s);
  }
  return names;
}

std::string listed(const std::vector<std::string>& names) {
  std::string out;
  for (const std::string& n : names) out += (out.empty() ? "" : ", ") + n;
  return out;
}

// " chamfer", " bench latency": the command path after "ncd".
std::string path_of(const std::vector<const CLI::App*>& chain) {
  std::string out;
  for (const CLI::App* c : chain) {
    if (!c->get_name().empty()) out += " " + c->get_name();
  }
  return out;
}

std::string without_dashes(const std::string& flag) {
  return flag.substr(std::min(flag.find_first_not_of('-'), flag.size()));
}

std::string unknown_command(const std::string& word, const std::vector<const CLI::App*>& chain,
                            const CLI::App& parent) {
  const std::vector<std::string> names = command_names(parent);
  const std::optional<std::string> near = nearest(word, names);
  const std::string where = path_of(chain);
  return "unknown command '" + word + "'" + (where.empty() ? "" : " of ncd" + where) +
         (near ? "; did you mean '" + *near + "'?" : "; the commands are " + listed(names)) +
         " (`ncd help" + where + "` lists them)";
}

// A token that is a value, not a flag: a negative number or a list of them ("-1,2.5,-3").
bool is_number_like(const std::string& token) {
  if (token.size() < 2 || token[0] != '-') return false;
  const char c = token[1];
  return std::isdigit(static_cast<unsigned char>(c)) != 0 || c == '.';
}

// The flag a token names ("--feed=300" names --feed), or none if it is not a flag.
std::optional<std::string> flag_of(const std::string& token) {
  if (token.size() < 2 || token[0] != '-' || token == "--" || is_number_like(token)) {
    return std::nullopt;
  }
  if (token[1] == '-') return token.substr(0, token.find('='));
  return token.substr(0, 2);  // -q, or -o FILE / -oFILE: the letter names it
}

// Checks the flags after the command path against the innermost command; descends into a
// nested command (`bench latency`) where a word names one.
std::optional<std::string> check_flags(const CLI::App& app, const std::vector<std::string>& args,
                                       std::size_t from, std::vector<const CLI::App*> chain) {
  const CLI::App* cmd = chain.back();
  for (std::size_t i = from; i < args.size(); ++i) {
    const std::string& token = args[i];
    if (token == "--") break;  // what follows is positional
    if (const CLI::App* sub = find_command(*cmd, token)) {
      chain.push_back(sub);
      cmd = sub;
      continue;
    }
    const std::optional<std::string> flag = flag_of(token);
    if (!flag) {
      // A word where only a command can stand (`ncd bench latncy`).
      const bool takes_words =
          !cmd->get_options([](const CLI::Option* o) { return o->get_positional(); }).empty();
      if (!takes_words && !command_names(*cmd).empty() && token.rfind('-', 0) != 0) {
        return unknown_command(token, chain, *cmd);
      }
      continue;
    }
    if (cmd->get_option_no_throw(*flag) != nullptr) continue;
    if (cmd->get_help_ptr() != nullptr && cmd->get_help_ptr()->check_name(*flag)) continue;
    if (app.get_help_ptr() != nullptr && app.get_help_ptr()->check_name(*flag)) continue;
    // Compared without their dashes, so that `-z` is not "near" every short flag.
    std::vector<std::string> bare;
    for (const std::string& n : flag_names(*cmd)) bare.push_back(without_dashes(n));
    const std::optional<std::string> near = nearest(without_dashes(*flag), bare);
    const std::string where = path_of(chain);
    const std::string suggestion = near ? (near->size() == 1 ? "-" : "--") + *near : "";
    return "unknown flag " + *flag + " of ncd" + where +
           (near ? "; did you mean " + suggestion + "?" : std::string()) + " (`ncd help" + where +
           "` lists the flags)";
  }
  return std::nullopt;
}

// `ncd help [CMD [SUB]]` → `[CMD [SUB]] --help`.
GuidedArgs help_args(const CLI::App& app, const std::vector<std::string>& args) {
  GuidedArgs g;
  const CLI::App* parent = &app;
  std::vector<const CLI::App*> chain;
  for (std::size_t i = 1; i < args.size(); ++i) {
    const CLI::App* sub = find_command(*parent, args[i]);
    if (sub == nullptr) {
      g.error = unknown_command(args[i], chain, *parent);
      return g;
    }
    chain.push_back(sub);
    parent = sub;
    g.args.push_back(args[i]);
  }
  g.args.push_back("--help");
  return g;
}

}  // namespace

std::size_t edit_distance(std::string_view a, std::string_view b) {
  const std::size_t n = a.size(), m = b.size();
  std::vector<std::vector<std::size_t>> d(n + 1, std::vector<std::size_t>(m + 1));
  for (std::size_t i = 0; i <= n; ++i) d[i][0] = i;
  for (std::size_t j = 0; j <= m; ++j) d[0][j] = j;
  for (std::size_t i = 1; i <= n; ++i) {
    for (std::size_t j = 1; j <= m; ++j) {
      const std::size_t cost = a[i - 1] == b[j - 1] ? 0 : 1;
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + cost});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1]) {
        d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
      }
    }
  }
  return d[n][m];
}

std::optional<std::string> nearest(std::string_view word, const std::vector<std::string>& known) {
  if (word.size() < 3) return std::nullopt;  // a letter or two is near everything
  const std::size_t within = std::max<std::size_t>(2, word.size() / 3);
  std::optional<std::string> best;
  std::size_t best_d = within + 1;
  for (const std::string& k : known) {
    const std::size_t dist = edit_distance(word, k);
    if (dist < best_d) {
      best_d = dist;
      best = k;
    }
  }
  return best;
}

GuidedArgs guide_args(const CLI::App& app, std::vector<std::string> args) {
  if (args.empty()) return {std::move(args), std::nullopt};
  if (args[0] == "help") return help_args(app, args);
  if (args[0] == "-V") args[0] = "--version";
  const std::string& first = args[0];
  if (first.empty() || first[0] != '-') {
    const CLI::App* cmd = find_command(app, first);
    if (cmd == nullptr) return {{}, unknown_command(first, {}, app)};
    std::optional<std::string> error = check_flags(app, args, 1, {cmd});
    return {std::move(args), std::move(error)};
  }
  // ncd's own flags (--help, --version), then a command.
  std::optional<std::string> error = check_flags(app, args, 0, {&app});
  return {std::move(args), std::move(error)};
}

}  // namespace ncd::app
