#include "server/ops/config.h"

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <memory>
#include <utility>
#include <vector>

#include "server/ops/logging.h"

namespace forestmap::server {
namespace {

constexpr const char* kConfigFlag = "--config";
constexpr const char* kConfigVariable = "FORESTMAPD_CONFIG";

std::string Variable(const std::string& name) {
  const char* value = std::getenv(name.c_str());
  return value == nullptr ? std::string() : std::string(value);
}

// The flag of serving that key `name` of the file sets (one with a variable), or null.
const CLI::Option* ServeOption(const CLI::App& app, const std::string& name) {
  const CLI::Option* option = app.get_option_no_throw("--" + name);
  return option != nullptr && !option->get_envname().empty() ? option : nullptr;
}

// CLI11's TOML reader, refusing keys that are no flag of serving and sections, and leaving out
// the keys whose variable is set: CLI11 applies the file before the environment, and only to
// options still unset, so without this the file would win over the environment.
class ServeConfigFile : public CLI::ConfigTOML {
 public:
  explicit ServeConfigFile(const CLI::App* app) : app_(app) {}

  std::vector<CLI::ConfigItem> from_config(std::istream& input) const override {
    std::vector<CLI::ConfigItem> kept;
    for (CLI::ConfigItem& item : CLI::ConfigTOML::from_config(input)) {
      if (!item.parents.empty()) {
        throw CLI::ConfigError("configuration file: no [sections] (found [" +
                               CLI::detail::join(item.parents, ".") +
                               "]): every setting is a top-level key = value");
      }
      const CLI::Option* option = ServeOption(*app_, item.name);
      if (option == nullptr) {
        throw CLI::ConfigError("configuration file: unknown setting '" + item.name +
                               "' (the settings are the flags of serving without their "
                               "dashes, e.g. listen = \"127.0.0.1:50051\")");
      }
      if (Variable(option->get_envname()).empty()) kept.push_back(std::move(item));
    }
    return kept;
  }

 private:
  const CLI::App* app_;
};

// The configuration file when --config is not given: FORESTMAPD_CONFIG, else the default.
std::string DefaultConfigFile() {
  const std::string variable = Variable(kConfigVariable);
  return variable.empty() ? kDefaultConfigFile : variable;
}

// Where the value of `flag` came from: "command line", its variable, or the file.
std::string SourceOf(const CLI::App& app, const std::string& flag, int argc,
                     const char* const* argv) {
  for (int i = 1; i < argc; ++i) {
    const std::string word = argv[i];
    if (word == flag || word.rfind(flag + "=", 0) == 0) return "command line";
  }
  const CLI::Option* option = app.get_option_no_throw(flag);
  if (option != nullptr && !option->get_envname().empty() &&
      !Variable(option->get_envname()).empty()) {
    return "environment " + option->get_envname();
  }
  const std::string file = ConfigFileRead(app);
  return file.empty() ? "command line" : "configuration file " + file;
}

// True when the logs are to be JSON: --log-format as parsed so far, on the command line, or in
// its variable (the file is read late in parsing and may not have been yet).
bool JsonLogs(const CLI::App& app, int argc, const char* const* argv) {
  const CLI::Option* option = app.get_option_no_throw("--log-format");
  if (option != nullptr && !option->results().empty()) return option->results().back() == "json";
  for (int i = 1; i < argc; ++i) {
    const std::string word = argv[i];
    if (word == "--log-format=json" ||
        (word == "--log-format" && i + 1 < argc && std::string(argv[i + 1]) == "json")) {
      return true;
    }
  }
  return Variable(EnvName("--log-format")) == "json";
}

int ReportUsageError(const CLI::App& app, const CLI::ParseError& error, int argc,
                     const char* const* argv) {
  const std::string flag = FlagNamedIn(error.what(), &app);
  const std::string source = flag.empty() ? "" : SourceOf(app, flag, argc, argv);
  std::string message = error.what();
  const std::string prefix = "configuration file:";
  if (message.rfind(prefix, 0) == 0) {  // ServeConfigFile's, which does not know the file
    message.insert(prefix.size() - 1, " " + ConfigFileRead(app));
  }
  if (!source.empty() && source != "command line") message += " (from the " + source + ")";
  if (JsonLogs(app, argc, argv)) {
    ConfigureLogging({LogFormat::kJson, LogLevel::kInfo});
    std::vector<LogField> fields;
    if (!flag.empty()) fields.push_back({"flag", flag});
    if (!source.empty()) fields.push_back({"source", source});
    fields.push_back({"exit_code", std::to_string(kExitUsage), /*number=*/true});
    Log(LogLevel::kError, "usage error: " + message, fields);
  } else {
    std::cerr << app.get_name() << ": error: " << message << "\nRun " << app.get_name()
              << " --help for the flags.\n";
  }
  return kExitUsage;
}

}  // namespace

std::string EnvName(const std::string& flag) {
  std::string name = "FORESTMAPD_";
  for (const char c : flag.substr(flag.find_first_not_of('-'))) {
    name += c == '-' ? '_' : static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  }
  return name;
}

void ApplyEnvironmentAliases() {
  for (const char* flag : {"--db", "--listen"}) {
    const std::string name = EnvName(flag);
    const std::string alias = "FORESTMAP_" + name.substr(name.find('_') + 1);
    const std::string value = Variable(alias);
    if (Variable(name).empty() && !value.empty()) setenv(name.c_str(), value.c_str(), 1);
  }
}

void AddConfigurationSources(CLI::App& app, const std::string& version) {
  for (CLI::Option* option : app.get_options()) {
    const std::string flag = option->get_name();
    if (flag.rfind("--", 0) == 0 && flag != "--help") option->envname(EnvName(flag));
  }
  app.set_config(kConfigFlag, DefaultConfigFile(),
                 "settings file (TOML: flag = value, e.g. listen = \"0.0.0.0:50051\"); read "
                 "when present; '' for none; also FORESTMAPD_CONFIG. Command line > "
                 "FORESTMAPD_* variables > this file > defaults");
  app.config_formatter(std::make_shared<ServeConfigFile>(&app));
  app.allow_config_extras(CLI::config_extras_mode::error);
  app.set_version_flag("--version", version, "print the version, git commit and build type");
}

int ParseConfiguration(CLI::App& app, int argc, const char* const* argv) {
  try {
    const std::string variable = Variable(kConfigVariable);
    if (!variable.empty() && !std::filesystem::is_regular_file(variable)) {
      throw CLI::FileError(std::string(kConfigVariable) + "=" + variable + ": no such file (" +
                           kConfigFlag + " '' reads none)");
    }
    app.parse(argc, argv);
    return -1;
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    return ReportUsageError(app, e, argc, argv);
  }
}

std::string ConfigFileRead(const CLI::App& app) {
  const CLI::Option* config = app.get_config_ptr();
  if (config == nullptr) return "";
  // CLI11 records the default file among the results only once it was read without error.
  const std::string file =
      config->results().empty() ? config->get_default_str() : config->results().front();
  return !file.empty() && std::filesystem::is_regular_file(file) ? file : "";
}

std::string FlagNamedIn(const std::string& text, const CLI::App* app) {
  for (size_t at = text.find("--"); at != std::string::npos; at = text.find("--", at + 2)) {
    size_t end = at + 2;
    while (end < text.size() &&
           (std::isalnum(static_cast<unsigned char>(text[end])) != 0 || text[end] == '-')) {
      ++end;
    }
    const std::string flag = text.substr(at, end - at);
    if (flag.size() > 2 && (app == nullptr || app->get_option_no_throw(flag) != nullptr)) {
      return flag;
    }
  }
  return "";
}

std::vector<std::string> ChangedFlags(const CLI::App& before, const CLI::App& after,
                                      const std::vector<std::string>& ignored) {
  const auto value = [](const CLI::Option& option) {
    std::string text = option.get_default_str();
    if (!option.results().empty()) text = CLI::detail::join(option.results(), "\n");
    return text;
  };
  std::vector<std::string> changed;
  for (const CLI::Option* option : after.get_options()) {
    const std::string flag = option->get_name();
    if (std::find(ignored.begin(), ignored.end(), flag) != ignored.end()) continue;
    const CLI::Option* old = before.get_option_no_throw(flag);
    if (old != nullptr && value(*old) != value(*option)) changed.push_back(flag);
  }
  return changed;
}

}  // namespace forestmap::server
