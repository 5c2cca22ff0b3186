// SqliteMapStore: uploads that create their map (schema step 7). Their trees are written as the
// final rows of the hidden map, so that the commit only reveals the map row; these helpers keep
// the index in the upload of each staged row, for the message of a duplicate id.

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "storage/sqlite/internal.h"

namespace forestmap::storage::sqlite {

void RecordChunk(Database& db, int64_t upload_id, int64_t first_rowid, int64_t first_index,
                 const std::vector<size_t>& order) {
  std::string packing(order.size() * 4, '\0');
  for (size_t k = 0; k < order.size(); ++k) {
    const auto index = static_cast<uint32_t>(order[k]);
    for (size_t b = 0; b < 4; ++b)
      packing[k * 4 + b] = static_cast<char>((index >> (8 * b)) & 0xff);
  }
  Statement insert(db,
                   "INSERT INTO upload_chunks (upload_id, first_rowid, first_index, packing) "
                   "VALUES (?1, ?2, ?3, ?4)",
                   upload_id, first_rowid, first_index);
  insert.BindBlob(4, packing);
  insert.Run();
}

std::optional<int64_t> StagedIndex(Database& db, int64_t upload_id, int64_t map_id,
                                   int64_t tree_id) {
  Statement row(db,
                "SELECT rowid FROM trees INDEXED BY trees_current WHERE map_id = ?1 AND "
                "tree_id = ?2 AND valid_to = " FORESTMAP_CURRENT,
                map_id, tree_id);
  if (!row.Step()) return std::nullopt;
  const int64_t rowid = row.ColumnInt64(0);
  Statement chunk(db,
                  "SELECT first_rowid, first_index, packing FROM upload_chunks WHERE "
                  "upload_id = ?1 AND first_rowid <= ?2 ORDER BY first_rowid DESC LIMIT 1",
                  upload_id, rowid);
  if (!chunk.Step()) return std::nullopt;
  const std::string packing = chunk.ColumnBlob(2);
  const auto at = static_cast<size_t>(rowid - chunk.ColumnInt64(0)) * 4;
  if (at + 4 > packing.size()) return std::nullopt;
  uint32_t index = 0;
  for (size_t b = 0; b < 4; ++b) {
    index |= static_cast<uint32_t>(static_cast<unsigned char>(packing[at + b])) << (8 * b);
  }
  return chunk.ColumnInt64(1) + index;
}

void ForgetChunks(Database& db, int64_t upload_id) {
  // The records are indices, nothing to scrub: without secure_delete (on in Debian's SQLite)
  // their freed pages go to the free list unwritten, a page per ~1,000 of them.
  const bool secure_delete = db.QueryInt64("PRAGMA secure_delete") != 0;
  const auto restore = [&] {
    db.Execute(secure_delete ? "PRAGMA secure_delete = ON" : "PRAGMA secure_delete = OFF");
  };
  db.Execute("PRAGMA secure_delete = OFF");
  try {
    if (upload_id >= 0) {
      Statement(db, "DELETE FROM upload_chunks WHERE upload_id = ?1", upload_id).Run();
    } else {
      db.Execute("DELETE FROM upload_chunks WHERE upload_id NOT IN (SELECT id FROM uploads)");
    }
  } catch (...) {
    restore();
    throw;
  }
  restore();
}

}  // namespace forestmap::storage::sqlite
