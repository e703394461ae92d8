// Where public datasets live: never in the repository, always behind this setting.
#pragma once

#include <string>

namespace uwbloc::data {

/// The data directory: `flag` if given, else $UWBLOC_DATA_DIR, else `../shared/datasets`
/// beside the project's folder (found from the running program's location) or beside the
/// working directory, when that folder exists; "" if none.
std::string resolveDataDir(const std::string& flag = "");

/// The project's own datasets/ folder (the checkout's, or share/uwbloc/datasets when installed);
/// "" when none is found.
std::string projectDatasetsDir();

/// A user-given path: as given if it exists, else relative to the data directory, else relative
/// to the project's datasets/ folder (the checkout's, or share/uwbloc/datasets when installed),
/// so that "mrpt_uwb_demo.ini" finds the bundled manifest.
/// Returns the path as given when nothing matches, so that the error names it.
std::string resolveInputPath(const std::string& path, const std::string& data_dir);

}  // namespace uwbloc::data
