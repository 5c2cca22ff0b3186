#pragma once
// The evidence of absence of one Observe (docs/design.md, "Evidence of absence"). For each frame
// with a pose, even one without trees, the trees near its sensor that it should have seen
// (algorithms::ExpectTrees, the sensor's range and detection rate learned from the call's frames
// with algorithms::SensorPool, or stated), weighed as sightings and misses into each tree's
// evidence (algorithms::AddView), which is stored with the tree (storage::TreeRecord::
// last_seen_unix_ms, evidence). A tree the evidence shows gone leaves the map in the call's
// version, its rows with it, and its evidence goes into the removal log
// (storage::MapChanges::removals): it stays in the history and comes back with RestoreVersion.
// Used by server/app/map_merger.h inside the store's write transaction.

#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <span>
#include <string>
#include <vector>

#include "algorithms/merging/absence.h"
#include "algorithms/merging/absence_evidence.h"
#include "algorithms/merging/map_merge.h"
#include "storage/map_store.h"

namespace forestmap::server {

struct AbsenceSettings {
  algorithms::AbsenceOptions absence;  // range and detection_probability 0: learned
  algorithms::AbsenceEvidenceOptions evidence;
};

// The 1-sigma uncertainty of a frame's pose.
struct PoseSigma {
  double xy = 0;   // m, per horizontal axis
  double yaw = 0;  // rad
};

// A live tree near a frame's sensor.
struct NearTree {
  algorithms::MapTree tree;
  bool candidate = false;
};

class AbsenceLedger {
 public:
  // `sigmas`: one per frame of the call (missing ones are 0).
  AbsenceLedger(std::string source, int64_t time_unix_ms, AbsenceSettings settings,
                std::vector<PoseSigma> sigmas);

  // A stored tree the call may weigh; the first load of an id counts.
  void Load(const storage::TreeRecord& tree);
  bool IsGone(int64_t id) const { return gone_.count(id) != 0; }
  const std::set<int64_t>& gone() const { return gone_; }

  struct View {
    std::vector<NearTree> trees;       // as classified: established first, then candidates
    algorithms::AbsenceResult result;  // parallel to `trees`
  };
  // Classifies the live trees near the sensor of frame `index` of the call (`frame`).
  View Classify(size_t index, const algorithms::FrameObservations& frame,
                std::vector<NearTree> nearby);
  // After the frame merged: its sightings and misses, and the trees it started (seen by it), which
  // are also weighed against the call's earlier views of their places (one source: within a pass
  // a stem does not appear). Returns how many trees it missed; the trees shown gone join gone().
  int Apply(const View& view, int64_t frame_id, std::span<const algorithms::TreeEstimate> started);

  // The trees the call started (`started`: live, not stored), weighed against the views of the
  // same source that earlier calls stored (its observation rows around them, frame by frame, as
  // views from the rows' sensor positions), as Apply weighs them against the call's own views.
  void LookBackStored(storage::MergeReader& reader,
                      std::span<const algorithms::TreeEstimate> started);

  // Into the merge's changes: every gone stored tree removed with its current rows and logged;
  // every put tree stamped with its evidence (what the call learned, else what was stored, else
  // seen now: a tree new to the map); stored trees whose evidence alone changed put again.
  void Finish(storage::MergeReader& reader, storage::MapChanges& changes) const;

 private:
  // An earlier view of the source, as it was classified.
  struct PastView {
    int64_t frame_id = 0;
    algorithms::AbsenceObservation observation;
    algorithms::AbsenceOptions options;            // the sensor model it was classified with
    std::vector<algorithms::MapTree> established;  // a view of the call: those around it
    std::vector<char> standing;
  };

  algorithms::TreeEvidence& EvidenceOf(int64_t id);
  // Seen since the survey (what this call weighed, else `stored`'s last-seen time).
  bool Standing(int64_t id, const storage::TreeRecord* stored) const;
  void LookBack(std::span<const algorithms::TreeEstimate> started);
  // `established` and `standing`: the confirmed trees around the view (its own, or a stored
  // view's, read once for all).
  void LookBackAt(const PastView& view, std::span<const algorithms::MapTree> established,
                  std::span<const char> standing,
                  std::span<const algorithms::TreeEstimate> started);

  std::string source_;
  int64_t time_;
  AbsenceSettings settings_;
  std::vector<PoseSigma> sigmas_;
  algorithms::SensorPool pool_;
  std::vector<PastView> views_;
  std::optional<PastView> current_;                       // classified, not yet applied
  std::map<int64_t, storage::TreeRecord> stored_;         // loaded trees, as stored
  std::map<int64_t, algorithms::TreeEvidence> evidence_;  // weighed by this call
  std::set<int64_t> gone_;
};

// A tree's stored evidence as the algorithms hold it (none when unset or unreadable), and back.
algorithms::TreeEvidence ToTreeEvidence(const storage::TreeRecord& tree);
void SetEvidence(storage::TreeRecord& tree, const algorithms::TreeEvidence& evidence);

}  // namespace forestmap::server
