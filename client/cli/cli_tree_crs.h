#pragma once
// The CRS of tree files on their way into a map (geo/crs.h through PROJ): --to-crs reprojection,
// the checks that the trees are where their CRS says, and CRS descriptions for messages.

#include <CLI/CLI.hpp>
#include <ostream>
#include <string>
#include <vector>

#include "client/cli/cli_tree_input.h"

namespace forestmap::client {

// Adds --to-crs to `command`, storing its text.
void AddToCrsOption(CLI::App& command, std::string& to_crs);

// Puts `rows`, read from `path` in CRS `from` (the file's own or --crs; empty: unknown), into
// CRS `to` (--to-crs; "utm": the WGS 84 / UTM zone of their centre) and returns the CRS they are
// then in. Only x and y move; heights are kept. Without `to`, a `from` whose coordinates are not
// metres on a plane (degrees, feet) is refused, naming the --to-crs that would take it. Throws
// CommandError naming the file (and the tree PROJ cannot move).
std::string ReprojectTrees(std::vector<MapTreeRow>& rows, const std::string& path,
                           const std::string& from, const std::string& to, std::ostream& log);

// Warns on `log` when the trees of `path` cannot be where `crs` says: closer together than trees
// stand (half of them under 5 cm from their nearest neighbour: x and y are not metres), their
// centre outside the area of use of `crs` (a wrong CRS), or a unit of `crs` there more than 1%
// off a metre on the ground (Web Mercator).
void CheckTreePlacement(const std::vector<MapTreeRow>& rows, const std::string& path,
                        const std::string& crs, std::ostream& log);

// The CRS of trees read from `path`: --crs (`given`) or the file's own (`declared`); refuses a
// --crs that contradicts the file's CRS (it would relabel the coordinates without moving them).
std::string CrsOfTrees(const std::string& path, const std::string& given,
                       const std::string& declared);

// Whether coordinates in `crs` are metres on a plane (true for an empty, unknown CRS), and
// whether two CRSs are the same; throw CommandError for a CRS PROJ does not know.
bool InMetres(const std::string& crs);
bool SameCrs(const std::string& a, const std::string& b);

// "EPSG:n (name)", or the CRS's name, for messages (ShortCrs when PROJ does not know it).
std::string DescribedCrs(const std::string& crs);

}  // namespace forestmap::client
