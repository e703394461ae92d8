// Importer for the CMU Plaza range + odometry data (as shipped with GTSAM's examples):
// Plaza2_DR.txt (t, distance, heading change), Plaza2_TD.txt (t, sender, beacon, range),
// Plaza2_TL.txt (beacon x y), Plaza2_GT.txt (t x y theta).
// Every distribution's layout is read: each table from its <prefix>_<NAME>.txt when present,
// else from the matrix NAME (DR, TD, TL, GT) of <prefix>.mat, read with libmatio (the layout in
// which GTSAM ships Plaza1: _DR.txt, _TD.txt and a .mat holding the reference and beacons).
//
// The odometry's heading convention differs from the reference's by pi (dead reckoning from
// (x0, y0, pi + theta0) follows it), i.e. the robot moves backwards along the reference heading:
// the increments are written as (-d cos(dh/2), -d sin(dh/2), dh) so that they compose from the
// reference's own start pose. Beacons and tag are at height 0 (a planar data set).
#pragma once

#include <string>

#include "uwbloc/dataset/hanyang_import.hpp"

namespace uwbloc::data {

/// `dir` holds the Plaza files (the run's prefix is found from <prefix>_DR.txt, else <prefix>.mat).
ImportSummary importPlaza(const std::string& dir, const std::string& out_dir);

}  // namespace uwbloc::data
