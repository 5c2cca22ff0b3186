#include "algorithms/relocalizer.h"
// Placeholder while the real implementation lands.
#include <stdexcept>
namespace forestmap::algorithms {
class MapIndexImpl { public: std::vector<MapTree> trees; };
void MapIndexOptions::Check() const {}
void RelocalizerOptions::Check() const {}
MapIndex::MapIndex(std::vector<MapTree> trees, const MapIndexOptions&) : impl_(new MapIndexImpl{std::move(trees)}) {}
MapIndex::~MapIndex() = default;
size_t MapIndex::size() const { return impl_->trees.size(); }
const std::vector<MapTree>& MapIndex::trees() const { return impl_->trees; }
bool MapIndex::has_z() const { return true; }
bool MapIndex::has_dbh() const { return true; }
size_t MapIndex::MemoryBytes() const { return 0; }
RelocalizeResult Relocalize(const MapIndex&, const RelocalizeQuery&, const RelocalizerOptions&) { return {}; }
const char* ToString(RelocalizeStatus s) { switch (s) { case RelocalizeStatus::kLocalized: return "localized"; case RelocalizeStatus::kAmbiguous: return "ambiguous"; default: return "not_found"; } }
}
