#pragma once
/// @file log.hpp
/// The one logger of tetfsi (spdlog). Libraries log through `tetfsi::logger()`, never
/// std::cout. Messages go to stderr so that stdout stays free for reports.
#include <memory>

#include <spdlog/spdlog.h>

namespace tetfsi {

/// The shared logger (created on first use, name "tetfsi", stderr, level info).
spdlog::logger& logger();

/// Set the level by name: "trace", "debug", "info", "warn", "error", "off".
/// @throws InputError on an unknown name.
void set_log_level(const std::string& level);

}  // namespace tetfsi
