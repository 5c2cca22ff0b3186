#pragma once
// Internal to server/grpc's validation: checks of single fields, each throwing ValidationError
// (validation.h) that names the field's path.

#include <string>

#include "forestmap/v1/geometry.pb.h"

namespace forestmap::server {

std::string Number(double v);  // shortest text that reads back as v (10 digits)
void CheckFinite(double v, const std::string& path);
void CheckVector(const v1::Vector3& v, const std::string& path);  // every component finite
// What is wrong with `v` as a coordinate of a local map frame (finite, |v| < limit m): the text
// after "<field> is ", or empty.
std::string CoordinateProblem(double v, double limit);
void CheckCoordinate(double v, double limit, const std::string& path);
void CheckDbh(double dbh, const std::string& path);  // finite, in [0, kMaxDbh]
// A position: x and y within kMaxHorizontalCoordinate, z within kMaxVerticalCoordinate.
void CheckPosition(const v1::Vector3& v, const std::string& path);
// A direction: finite and not zero (its length does not matter).
void CheckDirection(const v1::Vector3& v, const std::string& path);

}  // namespace forestmap::server
