#pragma once
// cpp-httplib for server/http. Its <resolv.h> defines the macro `_res`, which breaks any later
// header naming a member `_res` (Eigen's do) when files compile together in a unity batch: the
// macro goes with this include.

#include <httplib.h>
#undef _res
