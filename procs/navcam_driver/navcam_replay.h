#pragma once
// LCM adapter of navcam_driver: replays a Navcam manifest (or the manifest
// a folder of PDS3 products makes, navcam_pds.h) as
//   ROVER_SITE      site_event_t  ARRIVED (num_pairs = rows of the site) at the site's first pair time,
//                                 IMAGING_DONE (num_pairs = pairs published) at its last pair time
//   NAVCAM_STEREO   stereo_image_t one per good manifest row, images as 8-bit grey
// Sites are the runs of equal site ids in time order.

#include <string>

#include "navcam_manifest.h"
#include "navcam_pds.h"
#include "vloc/lcm_io/replay_pacer.h"
#include "vloc/lcm_io/transport.h"

namespace vloc {

class OptionsReader;

struct NavcamDriverOptions {
  std::string manifest;                        // path of the manifest YAML (--manifest overrides); a folder = pds
  std::string pds;                             // folder of PDS3 products read without a manifest (--pds overrides)
  NavcamPdsOptions pds_options;                // how PDS products are grouped (navcam_pds.h)
  std::string stereo_channel = "NAVCAM_STEREO";  // stereo_image_t
  std::string site_channel = "ROVER_SITE";       // site_event_t
  std::string encoding = "png";                // png, jpeg or gray8
  double speed = 1.0;                          // real-time factor on the recorded times; 0 = as fast as possible

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

struct NavcamReplaySummary {
  int sites = 0;
  int pairs_published = 0;
  int pairs_skipped = 0;  // bad rows and unreadable images
};

// Publishes the manifest's good entries; reports each bad one in one log line.
NavcamReplaySummary ReplayNavcam(const NavcamDriverOptions& options, const NavcamManifest& manifest,
                                 Transport& transport, ReplayPacer& pacer);

}  // namespace vloc
