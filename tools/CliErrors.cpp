#include "CliErrors.h"

#include "bake/LibraryErrors.h"
#include "stream/util/Diagnostics.h"
#include "stream/util/Error.h"
#include "stream/util/StopRequest.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cctype>
#include <cstdio>
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
        // A bake under an address-space limit says what it needs before this; what gets here ran
        // out where no plan reaches (a command without one, or the allocator's own overhead).
        say(prefix + "out of memory (give the process more memory; a bake can take --memory-budget or fewer receivers)");
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

namespace {

/// The names of @p app's commands, in the order they were added.
std::vector<std::string> commandNames(CLI::App& app) {
    std::vector<std::string> names;
    for (const CLI::App* command : app.get_subcommands([](CLI::App*) { return true; })) names.push_back(command->get_name());
    return names;
}

bool contains(const std::vector<std::string>& names, const std::string& name) {
    return std::find(names.begin(), names.end(), name) != names.end();
}

int usageLine(const std::string& text) {
    printDiagnostic("penumbra: error: " + printableLine(text) + "\n");
    return 2;
}

}  // namespace

int reportUsageError(CLI::App& app, const CLI::ParseError& e, int argc, char** argv) {
    if (e.get_exit_code() == 0) {
        // `merge` runs as `bake --merge` (rewriteMergeCommand): its help names it, not bake.
        if (argc > 1 && std::string(argv[1]) == "merge" && dynamic_cast<const CLI::CallForHelp*>(&e))
            for (CLI::App* bake : app.get_subcommands([](CLI::App* c) { return c->get_name() == "bake"; })) {
                std::string help = bake->help();
                for (int line = 0; line < 2 && help.find('\n') != std::string::npos; ++line) help.erase(0, help.find('\n') + 1);
                std::fputs("merge shard files into a bake's outputs (the bake's options; --shard-dir is required)\n"
                           "Usage: penumbra merge [OPTIONS] scene\n",
                           stdout);
                std::fputs(help.c_str(), stdout);
                return 0;
            }
        return app.exit(e);
    }
    const std::vector<std::string> commands = commandNames(app);
    const std::string first = argc > 1 ? argv[1] : "", next = argc > 2 ? argv[2] : "";
    const std::string listed = fmt::format("{}", fmt::join(commands, ", "));
    if (!first.empty() && first[0] != '-' && !contains(commands, first))
        return usageLine(fmt::format("unknown command '{}' (commands: {}; see penumbra --help)", first, listed));
    // No command, or an option before any command, or a command of commands (bench) without one
    // of its own: say what is missing, not CLI11's "a subcommand is required".
    const bool required = dynamic_cast<const CLI::RequiredError*>(&e) != nullptr;
    if (required && app.get_subcommands().empty())
        return usageLine(fmt::format("{} (commands: {}; see penumbra --help)",
                                     first.empty() ? std::string("no command given") : "unknown option '" + first + "' before a command", listed));
    std::vector<std::string> subcommands;
    for (CLI::App* c : app.get_subcommands([&](CLI::App* c) { return c->get_name() == first; })) subcommands = commandNames(*c);
    const bool nextIsSub = contains(subcommands, next);
    if (required && !subcommands.empty() && !nextIsSub) {
        const std::string known = fmt::format("{}", fmt::join(subcommands, ", "));
        if (next.empty() || next[0] == '-') return usageLine(fmt::format("{} needs one of: {} (see penumbra {} --help)", first, known, first));
        return usageLine(fmt::format("unknown {} '{}' (known: {}; see penumbra {} --help)", first, next, known, first));
    }
    // One line, as every other error: the parser's message, and where the usage is explained.
    std::string message = e.what();
    if (!message.empty()) message[0] = char(std::tolower(static_cast<unsigned char>(message[0])));
    const std::string where = !contains(commands, first) ? "" : nextIsSub ? first + " " + next + " " : first + " ";
    return usageLine(fmt::format("{} (see penumbra {}--help)", message, where));
}

}  // namespace penumbra
