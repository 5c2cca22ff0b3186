#include "algorithms/merging/absence_evidence.h"

#include <cmath>

#include "algorithms/core/check.h"

namespace forestmap::algorithms {

void AbsenceEvidenceOptions::Check() const {
  Require(shared_miss > 0 && shared_miss < 1,
          "AbsenceEvidenceOptions.shared_miss must be in (0, 1)", shared_miss);
  // alpha < eps^2: neither one group (at most log(1 / eps)) nor two can remove a tree.
  Require(false_removal > 0 && false_removal < shared_miss * shared_miss,
          "AbsenceEvidenceOptions.false_removal must be in (0, shared_miss^2)", false_removal);
  Require(false_retirement > 0 && false_retirement < 1,
          "AbsenceEvidenceOptions.false_retirement must be in (0, 1)", false_retirement);
}

double AbsenceEvidenceOptions::Threshold(bool candidate) const {
  return std::log(1.0 / (candidate ? false_retirement : false_removal));
}

void AddSighting(TreeEvidence& evidence, const std::string& group, int64_t time) {
  evidence.groups.clear();
  evidence.misses = 0;
  ++evidence.sightings;
  if (time >= evidence.last_seen) {
    evidence.last_seen = time;
    evidence.last_seen_group = group;
  }
}

void AddMiss(TreeEvidence& evidence, const std::string& group, double detection_probability) {
  Require(detection_probability >= 0 && detection_probability < 1,
          "a detection probability must be in [0, 1)", detection_probability);
  ++evidence.misses;
  for (GroupMisses& g : evidence.groups) {
    if (g.group == group) {
      g.log_all_missed += std::log1p(-detection_probability);
      ++g.misses;
      return;
    }
  }
  evidence.groups.push_back({group, std::log1p(-detection_probability), 1});
}

double GoneLogLikelihoodRatio(const TreeEvidence& evidence, const AbsenceEvidenceOptions& options) {
  options.Check();
  const double eps = options.shared_miss;
  double sum = 0;
  for (const GroupMisses& g : evidence.groups) {
    sum -= std::log(eps + (1 - eps) * std::exp(g.log_all_missed));
  }
  return sum;
}

bool IsGone(const TreeEvidence& evidence, const AbsenceEvidenceOptions& options, bool candidate) {
  return GoneLogLikelihoodRatio(evidence, options) >= options.Threshold(candidate);
}

bool AddView(TreeEvidence& evidence, const TreeVisibility& view, bool candidate,
             const std::string& source, int64_t frame_id, int64_t time,
             const AbsenceEvidenceOptions& options) {
  if (view.visibility == Visibility::kSeen) AddSighting(evidence, source, time);
  if (view.visibility != Visibility::kMissed) return false;
  AddMiss(evidence, candidate ? source + "/" + std::to_string(frame_id) : source,
          view.detection_probability);
  return IsGone(evidence, options, candidate);
}

}  // namespace forestmap::algorithms
