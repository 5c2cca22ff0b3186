#pragma once
// What `forestmap-lab bench-changes --write DIR` writes for tests/bench/changes_server.sh: each
// drone pass as `forestmap observe --frames --poses` reads it, and the truth of the future forest.

#include <cstdint>
#include <fstream>
#include <set>
#include <string>
#include <vector>

#include "algorithms/core/geometry.h"
#include "algorithms/merging/map_merge.h"

namespace forestmap::client {

// DIR/pass<K>_trees.csv (frame,x,y,z,dbh: detections in the sensor frame) and
// DIR/pass<K>_poses.csv (frame,timestamp,x,y,z,qx,qy,qz,qw: every frame's map_from_sensor, also
// of frames that detected nothing).
class PassWriter {
 public:
  PassWriter(const std::string& dir, int pass);
  void Add(const algorithms::FrameObservations& frame);

 private:
  std::ofstream trees_, poses_;
};

// DIR/truth.json: {"felled": [ids], "new_trees": [[x, y, dbh], ...], "growth": m}.
void WriteChangesTruth(const std::string& dir, const std::set<int64_t>& felled,
                       const std::vector<algorithms::MapTree>& ingrowth, double growth);

}  // namespace forestmap::client
