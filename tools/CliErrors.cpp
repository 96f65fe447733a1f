#include "CliErrors.h"

#include "bake/LibraryErrors.h"
#include "stream/util/Diagnostics.h"
#include "stream/util/Error.h"
#include "stream/util/StopRequest.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cctype>
#include <new>
#include <optional>
#include <stdexcept>
#include <vector>

namespace penumbra {

int reportError(std::exception_ptr error, const std::string& context) {
    // Every message as one printable line, whatever bytes of the input it quotes (InputError's
    // are already; a library's own what() may quote a token of a damaged file).
    auto say = [](const std::string& line) { printDiagnostic(printableLine(line) + "\n"); };
    const std::string prefix = context.empty() ? "penumbra: error: " : "penumbra: error: " + context + ": ";
    try {
        std::rethrow_exception(error);
    } catch (const StopRequested& e) {  // SIGTERM under --checkpoint: what is saved, and how to go on
        say(fmt::format("penumbra: {}", e.what()));
        return kStoppedExitCode;
    } catch (const InputError& e) {
        say(fmt::format("penumbra: error: {}", e.what()));
    } catch (const std::bad_alloc&) {
        say("penumbra: error: out of memory (try --memory-budget or fewer receivers)");
    } catch (const std::length_error& e) {  // a size from the input beyond what a container can hold
        say(fmt::format("{}too large to hold in memory ({})", prefix, e.what()));
    } catch (const std::exception& e) {
        if (std::optional<std::string> message = libraryErrorMessage(e)) {
            say(prefix + *message);
            return 1;
        }
        say(fmt::format("penumbra: internal error: {}", e.what()));
        return 70;
    } catch (...) {
        say("penumbra: internal error: an unknown exception");
        return 70;
    }
    return 1;
}

int reportUsageError(CLI::App& app, const CLI::ParseError& e, int argc, char** argv) {
    if (e.get_exit_code() == 0) return app.exit(e);
    std::vector<std::string> commands;
    for (const CLI::App* command : app.get_subcommands([](CLI::App*) { return true; })) commands.push_back(command->get_name());
    const std::string first = argc > 1 ? argv[1] : "";
    if (!first.empty() && first[0] != '-' && std::find(commands.begin(), commands.end(), first) == commands.end()) {
        printDiagnostic(fmt::format("penumbra: error: unknown command '{}' (commands: {}; see penumbra --help)\n", first,
                                    fmt::join(commands, ", ")));
        return 2;
    }
    // No command, or an option before any command: say what comes first, not CLI11's "a
    // subcommand is required".
    if (dynamic_cast<const CLI::RequiredError*>(&e) && app.get_subcommands().empty()) {
        const std::string what = first.empty() ? std::string("no command given") : fmt::format("unknown option '{}' before a command", printableLine(first));
        printDiagnostic(fmt::format("penumbra: error: {} (commands: {}; see penumbra --help)\n", what, fmt::join(commands, ", ")));
        return 2;
    }
    // A command of commands (bench): name what it takes, and a usage error under one of its
    // commands points at that command's help.
    CLI::App* command = nullptr;
    for (CLI::App* c : app.get_subcommands([&](CLI::App* c) { return c->get_name() == first; })) command = c;
    std::vector<std::string> subNames;
    if (command)
        for (const CLI::App* sub : command->get_subcommands([](CLI::App*) { return true; })) subNames.push_back(sub->get_name());
    const std::string next = argc > 2 ? argv[2] : "";
    const bool nextIsSub = std::find(subNames.begin(), subNames.end(), next) != subNames.end();
    if (!subNames.empty() && !nextIsSub && dynamic_cast<const CLI::RequiredError*>(&e)) {
        const std::string known = fmt::format("{}", fmt::join(subNames, ", "));
        if (next.empty() || next[0] == '-')
            printDiagnostic(fmt::format("penumbra: error: {} needs one of: {} (see penumbra {} --help)\n", first, known, first));
        else
            printDiagnostic(fmt::format("penumbra: error: unknown {} '{}' (known: {}; see penumbra {} --help)\n", first,
                                        printableLine(next), known, first));
        return 2;
    }
    // One line, as every other error: the parser's message, and where the usage is explained.
    std::string message = e.what();
    if (!message.empty()) message[0] = char(std::tolower(static_cast<unsigned char>(message[0])));
    const std::string where = std::find(commands.begin(), commands.end(), first) == commands.end() ? ""
                              : nextIsSub ? first + " " + next + " " : first + " ";
    printDiagnostic(fmt::format("penumbra: error: {} (see penumbra {}--help)\n", printableLine(message), where));
    return 2;
}

}  // namespace penumbra
