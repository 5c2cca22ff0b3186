#pragma once
// Evidence that a map tree is gone, accumulated from observations classified by ExpectTrees
// (absence.h), and the rule that removes it.
//
// Two hypotheses: the tree still stands, or it is gone. A sighting is strong evidence that it
// stands, and resets the evidence of absence (what counts is the evidence since the tree was
// last seen). A miss by a view whose detector finds a standing tree with probability p has
// likelihood 1 - p if the tree stands and 1 if it is gone. The views of one group (one source:
// one drone, one pass) are not independent: one unmapped occluder (a bush), one error of that
// drone's poses or a tree its detector never finds would hide a standing tree from all of them.
// With probability eps (shared_miss) such a shared cause hides the tree from the whole group,
// otherwise its views miss independently, so a group's misses since the last sighting have
//   P(all missed | standing) = eps + (1 - eps) prod_i (1 - p_i),   P(all missed | gone) = 1,
// and contribute LLR_group = -log(eps + (1 - eps) prod_i (1 - p_i)) <= log(1 / eps) (for one
// miss, -log(1 - p (1 - eps))). Groups are independent: the evidence is the sum over groups.
// The tree is gone when the sum reaches log(1 / alpha): a likelihood ratio exceeds 1 / alpha
// under the "standing" hypothesis with probability at most alpha (Markov's inequality on the
// ratio, whose mean under that hypothesis is 1), so alpha (false_removal) bounds the chance that
// a standing tree is removed. With eps = 0.05 and alpha = 0.001 one group reaches at most 3.0
// of the 6.9 needed: a single drone, however many frames, never removes a tree; three groups
// that each missed it in several views do, as do four single misses at p = 0.9 (1.93 each).
// A candidate (a tree seen in too few views to be confirmed) retires by the same evidence at
// log(1 / 0.05) = 3.0: two single misses at p = 0.9.
//
// Frames and units as in algorithms/core/geometry.h. Thread-safety: plain values and functions.

#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "algorithms/merging/absence.h"

namespace forestmap::algorithms {

struct AbsenceEvidenceOptions {
  double shared_miss = 0.05;     // (0, 1), eps: a cause shared by a group's views hides a tree
  double false_removal = 0.001;  // (0, shared_miss^2), alpha: bound on removing a standing tree
  // (0, 1), bound on retiring a real candidate: a cheap error (the next view that sees the tree
  // starts it again, and a candidate needs several views to be confirmed anyway), so the usual
  // 5% test rather than the removal's 0.1%.
  double false_retirement = 0.05;
  void Check() const;                              // throws std::invalid_argument naming the field
  double Threshold(bool candidate = false) const;  // log(1 / alpha) or log(1 / false_retirement)
};

// Misses of one group since the tree was last seen.
struct GroupMisses {
  std::string group;
  double log_all_missed = 0;  // sum of log(1 - p_i) over the group's misses
  int misses = 0;
};

inline constexpr int64_t kNeverSeen = std::numeric_limits<int64_t>::min();

struct TreeEvidence {
  std::vector<GroupMisses> groups;  // since the last sighting, in order of first miss
  int64_t last_seen = kNeverSeen;   // caller's time (e.g. seconds), of the last sighting
  std::string last_seen_group;
  int sightings = 0;  // all time
  int misses = 0;     // since the last sighting
};

// A view saw the tree at `time`: the evidence of absence is reset.
void AddSighting(TreeEvidence& evidence, const std::string& group, int64_t time);

// A view of `group` should have seen the tree with probability `detection_probability`
// (in [0, 1)) and did not. Throws std::invalid_argument for a probability outside [0, 1).
void AddMiss(TreeEvidence& evidence, const std::string& group, double detection_probability);

// Sum over groups of LLR_group (natural log of the likelihood ratio gone / standing), >= 0.
double GoneLogLikelihoodRatio(const TreeEvidence& evidence,
                              const AbsenceEvidenceOptions& options = {});

// GoneLogLikelihoodRatio >= options.Threshold(candidate).
bool IsGone(const TreeEvidence& evidence, const AbsenceEvidenceOptions& options = {},
            bool candidate = false);

// One view's classification of a tree (ExpectTrees) added to its evidence: kSeen is a sighting by
// `source` at `time`; kMissed a miss grouped by `source` for an established tree, by the view
// itself (`source` + "/" + frame_id) for a candidate (whose alternative, a false stem, is one
// frame's error). Returns whether the tree is gone (IsGone) after a miss, else false.
bool AddView(TreeEvidence& evidence, const TreeVisibility& view, bool candidate,
             const std::string& source, int64_t frame_id, int64_t time,
             const AbsenceEvidenceOptions& options);

}  // namespace forestmap::algorithms
