#pragma once
// State a message can add, kept to a window of the newest sites: every map
// (or set) keyed by site id that a process fills from the bus is pruned
// with KeepNewestSites after each insertion, so a flood of site ids costs a
// bounded amount of memory and time, however many ids it carries.
//
//   std::map<int, PoseWithCovariance> poses;     // by site id
//   poses[site] = pose;
//   KeepNewestSites(&poses, options.max_sites);  // the highest ids stay

#include <cstddef>

namespace vloc {

// Erases the lowest keys of `by_site` (an ordered std::map or std::set keyed
// by site id) until at most `max_sites` remain; returns how many it erased.
template <class OrderedBySite>
size_t KeepNewestSites(OrderedBySite* by_site, size_t max_sites) {
  size_t erased = 0;
  while (by_site->size() > max_sites) {
    by_site->erase(by_site->begin());
    ++erased;
  }
  return erased;
}

}  // namespace vloc
