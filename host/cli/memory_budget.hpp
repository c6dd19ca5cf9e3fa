#pragma once
// `--memory-budget SIZE` for the commands that process scans (recognize, serve): the memory one scan's
// processing may use (ScanLimits::for_budget, docs/host-pipeline.md#memory-budget); and `--segment-row-step
// K`, which the budget accounts for.
#include <CLI/CLI.hpp>
#include <string>

#include "common/byte_size.hpp"
#include "common/error.hpp"
#include "host/io/scan.hpp"

namespace fs::host::cli {

// Adds the option; `text` receives SIZE as given (empty = the default budget). Checked at parse time.
inline CLI::Option* add_memory_budget_option(CLI::App* app, std::string& text) {
  return app
      ->add_option(
          "--memory-budget", text,
          "Memory one scan's processing may use (scan storage, ray table, cloud, recognizer): bytes or "
          "K/M/G/T (powers of 1024), e.g. 512M, 4G; default " +
              format_byte_size(ScanLimits::kDefaultBudgetBytes) +
              ". A scan that needs more is refused at its ScanBegin")
      ->check([](const std::string& s) {
        try {
          ScanLimits::for_budget(parse_byte_size(s));
          return std::string();
        } catch (const Error& e) {
          return std::string(e.what());
        }
      });
}

// The limits of `text` (as given to --memory-budget; empty = the default budget) for a recognizer of
// `threads` threads (RecognizeParams::threads: 0 = hardware concurrency) and segment_row_step.
inline ScanLimits memory_budget_limits(const std::string& text, int threads = 0, int segment_row_step = 1) {
  return ScanLimits::for_budget(text.empty() ? ScanLimits::kDefaultBudgetBytes : parse_byte_size(text),
                                threads, segment_row_step);
}

// `--segment-row-step K` for the commands that recognize scans (recognize, serve): RecognizeParams::
// segment_row_step.
inline CLI::Option* add_segment_row_step_option(CLI::App* app, int& step) {
  return app
      ->add_option(
          "--segment-row-step", step,
          "2: segment every other row where the rows lie more densely than the sweep's columns (about "
          "a third less segmentation time at 500 steps; docs/performance.md); 1 (default): every row")
      ->check(CLI::Range(1, 2));
}

}  // namespace fs::host::cli
