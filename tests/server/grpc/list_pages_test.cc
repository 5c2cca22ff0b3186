// ListMaps and ListVersions page by page (AIP-158) over an in-memory store: the pages concatenate
// to the whole list, page sizes have a default and a maximum, tokens are opaque and only continue
// the listing they came from.

#include "server/grpc/list_pages.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "server/grpc/status.h"
#include "storage/sqlite/store.h"
#include "tests/server/grpc/validation_test_util.h"

namespace forestmap::server {
namespace {

const Caller kEveryone;  // open mode: no token, every map readable

using test::BadField;

std::vector<std::string> AllNames(storage::MapStore& store, int page_size, int* pages) {
  std::vector<std::string> names;
  v1::ListMapsRequest request;
  request.set_page_size(page_size);
  *pages = 0;
  do {
    const v1::ListMapsResponse page = ListMapsPage(store, kEveryone, request);
    EXPECT_LE(page.maps_size(), page_size);
    for (const v1::Map& map : page.maps()) names.push_back(map.name());
    request.set_page_token(page.next_page_token());
    ++*pages;
  } while (!request.page_token().empty());
  return names;
}

std::vector<int64_t> AllVersions(storage::MapStore& store, const std::string& map, int limit,
                                 int page_size) {
  std::vector<int64_t> versions;
  v1::ListVersionsRequest request;
  request.set_name(map);
  request.set_limit(limit);
  request.set_page_size(page_size);
  do {
    const v1::ListVersionsResponse page = ListVersionsPage(store, request);
    EXPECT_LE(page.versions_size(), page_size);
    for (const v1::MapVersion& version : page.versions()) versions.push_back(version.version());
    request.set_page_token(page.next_page_token());
  } while (!request.page_token().empty());
  return versions;
}

// Map `name` with `versions` versions: created (1), then one tree per upload.
void AddMap(storage::MapStore& store, const std::string& name, int versions) {
  store.CreateMap(name, "", "");
  for (int v = 2; v <= versions; ++v) {
    storage::TreeRecord tree;
    tree.x = v;
    store.WriteTrees(name, {tree}, storage::WriteMode::kAppend);
  }
}

TEST(ListPagesTest, MapPagesConcatenateToAllMapsByName) {
  storage::SqliteMapStore store(":memory:");
  // Names whose order differs between bytes and a locale's collation ("B" < "a" bytewise).
  const std::vector<std::string> expected = {"A", "B", "a", "a-1", "a.2", "a_3", "b", "z"};
  for (auto it = expected.rbegin(); it != expected.rend(); ++it) store.CreateMap(*it, "", "");
  for (const int size : {1, 2, 3, 7, 8, 1000}) {
    int pages = 0;
    EXPECT_EQ(AllNames(store, size, &pages), expected) << size;
    // No empty page after a full one: the last page says there is no next.
    EXPECT_EQ(pages, (static_cast<int>(expected.size()) + size - 1) / size) << size;
  }
}

TEST(ListPagesTest, PageSizeHasADefaultAndAMaximum) {
  storage::SqliteMapStore store(":memory:");
  for (int i = 0; i < kMaxPageSize + 1; ++i) store.CreateMap(std::to_string(i) + "m", "", "");
  v1::ListMapsRequest request;
  EXPECT_EQ(ListMapsPage(store, kEveryone, request).maps_size(), kDefaultPageSize);
  request.set_page_size(kMaxPageSize + 500);  // more than the maximum gets the maximum
  const v1::ListMapsResponse page = ListMapsPage(store, kEveryone, request);
  EXPECT_EQ(page.maps_size(), kMaxPageSize);
  request.set_page_token(page.next_page_token());
  EXPECT_EQ(ListMapsPage(store, kEveryone, request).maps_size(), 1);
  request.set_page_size(-1);
  EXPECT_EQ(BadField([&] { ListMapsPage(store, kEveryone, request); }), "page_size");
}

TEST(ListPagesTest, TokensAreOpaqueAndOnlyContinueTheirListing) {
  storage::SqliteMapStore store(":memory:");
  AddMap(store, "alpha", 3);
  AddMap(store, "beta", 3);
  v1::ListMapsRequest maps;
  maps.set_page_size(1);
  const std::string maps_token = ListMapsPage(store, kEveryone, maps).next_page_token();
  ASSERT_FALSE(maps_token.empty());
  EXPECT_EQ(maps_token.find("alpha"), std::string::npos);  // not the name in plain text
  EXPECT_EQ(maps_token.find_first_not_of("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz"
                                         "0123456789-_"),
            std::string::npos);  // web-safe base64: fits a URL or a shell unquoted

  v1::ListVersionsRequest versions;
  versions.set_name("alpha");
  versions.set_page_size(1);
  const std::string versions_token = ListVersionsPage(store, versions).next_page_token();
  ASSERT_FALSE(versions_token.empty());

  for (const std::string& bad : {std::string("not a token"), std::string("Zm0x"),
                                 maps_token.substr(0, maps_token.size() - 2), versions_token}) {
    maps.set_page_token(bad);
    EXPECT_EQ(BadField([&] { ListMapsPage(store, kEveryone, maps); }), "page_token") << bad;
  }
  v1::ListVersionsRequest other_map = versions;
  other_map.set_name("beta");
  other_map.set_page_token(versions_token);
  EXPECT_EQ(BadField([&] { ListVersionsPage(store, other_map); }), "page_token");
  v1::ListVersionsRequest other_limit = versions;
  other_limit.set_limit(2);
  other_limit.set_page_token(versions_token);
  EXPECT_EQ(BadField([&] { ListVersionsPage(store, other_limit); }), "page_token");
  v1::ListVersionsRequest maps_token_for_versions = versions;
  maps_token_for_versions.set_page_token(maps_token);
  EXPECT_EQ(BadField([&] { ListVersionsPage(store, maps_token_for_versions); }), "page_token");
  // A changed page_size is honoured (AIP-158).
  v1::ListVersionsRequest bigger = versions;
  bigger.set_page_size(10);
  bigger.set_page_token(versions_token);
  EXPECT_EQ(ListVersionsPage(store, bigger).versions_size(), 2);
}

TEST(ListPagesTest, VersionPagesListTheHistoryOfTheFirstPage) {
  storage::SqliteMapStore store(":memory:");
  AddMap(store, "plot", 7);
  EXPECT_EQ(AllVersions(store, "plot", 0, 3), (std::vector<int64_t>{1, 2, 3, 4, 5, 6, 7}));
  EXPECT_EQ(AllVersions(store, "plot", 0, 7), (std::vector<int64_t>{1, 2, 3, 4, 5, 6, 7}));
  // limit: the newest versions, oldest first, however the pages cut them.
  EXPECT_EQ(AllVersions(store, "plot", 4, 3), (std::vector<int64_t>{4, 5, 6, 7}));
  EXPECT_EQ(AllVersions(store, "plot", 4, 1), (std::vector<int64_t>{4, 5, 6, 7}));

  // Versions made while paging are not in the listing; versions pruned meanwhile drop out.
  v1::ListVersionsRequest request;
  request.set_name("plot");
  request.set_page_size(2);
  const v1::ListVersionsResponse first = ListVersionsPage(store, request);
  ASSERT_EQ(first.versions_size(), 2);
  storage::TreeRecord tree;
  store.WriteTrees("plot", {tree}, storage::WriteMode::kAppend);  // version 8
  store.PruneVersions("plot", 5);                                 // keeps 4..8
  request.set_page_size(100);
  request.set_page_token(first.next_page_token());
  const v1::ListVersionsResponse rest = ListVersionsPage(store, request);
  std::vector<int64_t> versions;
  for (const v1::MapVersion& version : rest.versions()) versions.push_back(version.version());
  EXPECT_EQ(versions, (std::vector<int64_t>{4, 5, 6, 7}));
  EXPECT_TRUE(rest.next_page_token().empty());

  request.clear_page_token();
  request.set_limit(-1);
  EXPECT_EQ(BadField([&] { ListVersionsPage(store, request); }), "limit");
}

TEST(ListPagesTest, MapPagesSkipMapsTheCallerCannotRead) {
  storage::SqliteMapStore store(":memory:");
  for (const char* name : {"a1", "b1", "a2", "b2", "a3"}) store.CreateMap(name, "", "");
  Caller reader;
  reader.token = storage::TokenRecord{};
  reader.token->map_pattern = "a*";
  v1::ListMapsRequest request;
  request.set_page_size(2);
  std::vector<std::string> names;
  do {
    const v1::ListMapsResponse page = ListMapsPage(store, reader, request);
    for (const v1::Map& map : page.maps()) names.push_back(map.name());
    request.set_page_token(page.next_page_token());
  } while (!request.page_token().empty());
  EXPECT_EQ(names, (std::vector<std::string>{"a1", "a2", "a3"}));
}

}  // namespace
}  // namespace forestmap::server
