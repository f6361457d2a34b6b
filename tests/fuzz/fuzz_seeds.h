// Seed inputs for the fuzz targets, made by the project (nothing from ../shared is
// committed): small files of every format and file kind, one folder per target.
#pragma once

#include <filesystem>

namespace meshpde::fuzz {

/// Writes ROOT/TARGET/NAME seed files; returns how many.
int write_seeds(const std::filesystem::path& root);

}  // namespace meshpde::fuzz
