// Where public datasets live: never in the repository, always behind this setting.
#pragma once

#include <string>

namespace uwbloc::data {

/// The data directory: `flag` if given, else $UWBLOC_DATA_DIR, else `../shared/datasets`
/// beside the source checkout or the working directory when that folder exists; "" if none.
std::string resolveDataDir(const std::string& flag = "");

/// A user-given path: as given if it exists, else relative to the data directory, else relative
/// to the repository's datasets/ folder (so "mrpt_uwb_demo.ini" finds the bundled manifest).
/// Returns the path as given when nothing matches, so that the error names it.
std::string resolveInputPath(const std::string& path, const std::string& data_dir);

}  // namespace uwbloc::data
