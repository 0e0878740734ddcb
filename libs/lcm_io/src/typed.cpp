#include "vloc/lcm_io/typed.h"

#include <sstream>

namespace vloc {

std::string SubscriptionSummary(const std::vector<std::shared_ptr<SubscriptionStats>>& stats) {
  SubscriptionStats sum;
  for (const auto& s : stats) {
    if (!s) continue;
    sum.received += s->received;
    sum.decode_failures += s->decode_failures;
    sum.handler_failures += s->handler_failures;
    sum.dropped += s->dropped;
  }
  std::ostringstream o;
  o << "messages received " << sum.received << ", undecodable " << sum.decode_failures << ", rejected "
    << sum.handler_failures << ", dropped (queue full) " << sum.dropped;
  return o.str();
}

}  // namespace vloc
