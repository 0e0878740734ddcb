#include "navcam_replay.h"

#include <glog/logging.h>

#include <opencv2/imgproc.hpp>

#include "vloc/common/options.h"
#include "vloc/lcm_io/convert_rover.h"
#include "vloc/lcm_io/typed.h"

namespace vloc {

void NavcamDriverOptions::Visit(OptionsReader& r) {
  r.Optional("manifest", &manifest, "path of the manifest YAML (a folder: read as PDS products)");
  r.Optional("pds", &pds, "folder of PDS3 products (.IMG, .LBL + .IMG or browse .jpg/.png), read without a manifest");
  pds_options.Visit(r);
  r.Optional("stereo_channel", &stereo_channel, "stereo_image_t channel");
  r.Optional("site_channel", &site_channel, "site_event_t channel");
  r.Optional("encoding", &encoding, "png, jpeg or gray8", OneOf({"png", "jpeg", "gray8"}));
  r.Optional("speed", &speed, "real-time factor, 0 = as fast as possible", NonNegative());
  r.Relation("pds", manifest.empty() || pds.empty(), "must be empty when a manifest is given (one or the other)");
}

bool NavcamDriverOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

NavcamReplaySummary ReplayNavcam(const NavcamDriverOptions& options, const NavcamManifest& manifest,
                                 Transport& transport, ReplayPacer& pacer) {
  NavcamReplaySummary summary;
  summary.pairs_skipped = static_cast<int>(manifest.problems.size());
  const ImageEncoding encoding = ParseImageEncoding(options.encoding);
  const auto& entries = manifest.entries;
  for (size_t begin = 0; begin < entries.size();) {
    size_t end = begin;
    while (end < entries.size() && entries[end].site_id == entries[begin].site_id) ++end;
    const int site = entries[begin].site_id;
    const int rows = static_cast<int>(end - begin);
    ++summary.sites;
    if (!pacer.WaitFor(entries[begin].utime)) return summary;
    Publish(transport, options.site_channel, SiteEventToMessage({entries[begin].utime, site, SiteEventType::kArrived, rows}));
    int published = 0;
    for (size_t i = begin; i < end; ++i) {
      if (!pacer.WaitFor(entries[i].utime)) return summary;
      StereoPair pair;
      std::string error;
      if (!LoadNavcamPair(entries[i], &pair, &error)) {
        LOG(ERROR) << error;
        ++summary.pairs_skipped;
        continue;
      }
      pair.num_pairs = rows;
      if (encoding == ImageEncoding::kGray8)  // asked for grey: a colour camera's pairs go as their luminance
        for (cv::Mat* m : {&pair.left, &pair.right})
          if (m->channels() == 3) cv::cvtColor(*m, *m, cv::COLOR_BGR2GRAY);
      Publish(transport, options.stereo_channel, StereoPairToMessage(pair, encoding));
      ++published;
      ++summary.pairs_published;
    }
    Publish(transport, options.site_channel,
            SiteEventToMessage({entries[end - 1].utime, site, SiteEventType::kImagingDone, published}));
    begin = end;
  }
  return summary;
}

}  // namespace vloc
