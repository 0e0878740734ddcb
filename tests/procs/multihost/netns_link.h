#pragma once
// Test support for groups split across machines: two network namespaces
// ("vehicle" and "ground") joined by a veth pair, each end with the
// multicast route LCM needs, plus what a lossy or cut link does to them.
// Needs root (CAP_NET_ADMIN) and iproute2; loss uses tc netem where the
// kernel has it and an nftables random drop at each end's ingress where it
// does not (no delay then). Header-only; the namespaces are deleted (with
// their veth ends) by the destructor.

#include <fcntl.h>
#include <sched.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>
#include <tuple>
#include <vector>

namespace vloc::testing {

// Runs a shell command; returns its exit code, and its output in *out.
inline int Shell(const std::string& command, std::string* out = nullptr) {
  FILE* pipe = popen((command + " 2>&1").c_str(), "r");
  if (!pipe) return -1;
  std::string text;
  char buffer[512];
  while (fgets(buffer, sizeof(buffer), pipe)) text += buffer;
  const int status = pclose(pipe);
  if (out) *out = text;
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// The full path of `ip` (Subprocess execs without a PATH search).
inline std::string IpPath() {
  for (const char* p : {"/usr/sbin/ip", "/sbin/ip", "/usr/bin/ip", "/bin/ip"})
    if (access(p, X_OK) == 0) return p;
  return "ip";
}

class NetnsLink {
 public:
  // Namespaces <tag>v / <tag>g, veth ends <tag>-v / <tag>-g, 10.218.<n>.1/.2.
  explicit NetnsLink(const std::string& tag) : vehicle_(tag + "v"), ground_(tag + "g"),
                                               vehicle_dev_(tag + "-v"), ground_dev_(tag + "-g") {}
  ~NetnsLink() { Remove(); }
  NetnsLink(const NetnsLink&) = delete;
  NetnsLink& operator=(const NetnsLink&) = delete;

  // Creates both namespaces and the link. False with the failing command
  // and its output in *error (e.g. not root).
  bool Create(std::string* error) {
    Remove();
    const std::vector<std::string> steps = {
        "ip netns add " + vehicle_,
        "ip netns add " + ground_,
        "ip link add " + vehicle_dev_ + " type veth peer name " + ground_dev_,
        "ip link set " + vehicle_dev_ + " netns " + vehicle_,
        "ip link set " + ground_dev_ + " netns " + ground_,
        "ip -n " + vehicle_ + " addr add 10.218.0.1/24 dev " + vehicle_dev_,
        "ip -n " + ground_ + " addr add 10.218.0.2/24 dev " + ground_dev_,
        "ip -n " + vehicle_ + " link set lo up",
        "ip -n " + ground_ + " link set lo up",
        "ip -n " + vehicle_ + " link set " + vehicle_dev_ + " up multicast on",
        "ip -n " + ground_ + " link set " + ground_dev_ + " up multicast on",
        "ip -n " + vehicle_ + " route add 224.0.0.0/4 dev " + vehicle_dev_,
        "ip -n " + ground_ + " route add 224.0.0.0/4 dev " + ground_dev_,
    };
    for (const auto& s : steps) {
      std::string out;
      if (Shell(s, &out) != 0) {
        *error = "'" + s + "' failed: " + out;
        Remove();
        return false;
      }
    }
    created_ = true;
    return true;
  }

  void Remove() {
    Shell("ip netns del " + vehicle_);
    Shell("ip netns del " + ground_);
    created_ = false;
  }

  // argv run inside a namespace (ip netns exec NS argv...).
  std::vector<std::string> In(const std::string& ns, const std::vector<std::string>& argv) const {
    std::vector<std::string> out = {IpPath(), "netns", "exec", ns};
    out.insert(out.end(), argv.begin(), argv.end());
    return out;
  }

  // Packet loss (percent) and delay on both ends. Returns a description of
  // what was applied ("netem ..." or "nftables ..."), empty on failure.
  std::string AddLoss(double loss_percent, double delay_ms) {
    const std::string netem = " root netem loss " + Num(loss_percent) + "% delay " + Num(delay_ms) + "ms";
    if (Shell("ip netns exec " + vehicle_ + " tc qdisc add dev " + vehicle_dev_ + netem) == 0 &&
        Shell("ip netns exec " + ground_ + " tc qdisc add dev " + ground_dev_ + netem) == 0) {
      loss_kind_ = "netem";
      return "tc netem loss " + Num(loss_percent) + "% delay " + Num(delay_ms) + " ms";
    }
    // No sch_netem in this kernel: drop a random loss_percent of the frames
    // arriving at each end (IP fragments, as a lossy radio loses them).
    // Only frames from the other end: a host's own multicast, looped back
    // to its local receivers, passes the ingress hook too.
    const int per_mille = static_cast<int>(loss_percent * 10 + 0.5);
    for (const auto& [ns, dev, peer] : {std::tuple{vehicle_, vehicle_dev_, std::string("10.218.0.2")},
                                        std::tuple{ground_, ground_dev_, std::string("10.218.0.1")}}) {
      const std::string rules_path = "/tmp/" + ns + "_loss.nft";
      std::ofstream(rules_path) << "table netdev vloc_loss {\n  chain ingress {\n    type filter hook ingress device "
                                << dev << " priority 0;\n    ip saddr " << peer << " numgen random mod 1000 < " << per_mille
                                << " counter drop\n  }\n}\n";
      const int rc = Shell("ip netns exec " + ns + " nft -f " + rules_path, &error_);
      std::remove(rules_path.c_str());
      if (rc != 0) return "";
    }
    loss_kind_ = "nft";
    return "nftables random drop of " + Num(loss_percent) + "% of the frames from the other end, at each end's ingress "
           "(no sch_netem in this kernel: no delay)";
  }
  void ClearLoss() {
    if (loss_kind_ == "netem") {
      Shell("ip netns exec " + vehicle_ + " tc qdisc del dev " + vehicle_dev_ + " root");
      Shell("ip netns exec " + ground_ + " tc qdisc del dev " + ground_dev_ + " root");
    } else if (loss_kind_ == "nft") {
      Shell("ip netns exec " + vehicle_ + " nft delete table netdev vloc_loss");
      Shell("ip netns exec " + ground_ + " nft delete table netdev vloc_loss");
    }
    loss_kind_.clear();
  }

  // Cuts the link at the ground end (its interface down: the vehicle end
  // loses its carrier), and brings it back with its multicast route (which
  // an interface going down loses; a real host's interface configuration
  // re-adds it).
  bool Cut() { return Shell("ip -n " + ground_ + " link set " + ground_dev_ + " down") == 0; }
  bool Restore() {
    return Shell("ip -n " + ground_ + " link set " + ground_dev_ + " up") == 0 &&
           Shell("ip -n " + ground_ + " route replace 224.0.0.0/4 dev " + ground_dev_) == 0;
  }

  // The output of the last failed AddLoss command.
  const std::string& error() const { return error_; }
  const std::string& vehicle() const { return vehicle_; }
  const std::string& ground() const { return ground_; }

 private:
  static std::string Num(double v) {
    char buf[32];
    std::snprintf(buf, sizeof(buf), "%g", v);
    return buf;
  }
  std::string vehicle_, ground_, vehicle_dev_, ground_dev_;
  std::string loss_kind_;
  std::string error_;
  bool created_ = false;
};

// Moves the calling thread into network namespace `ns` while it lives
// (sockets opened meanwhile stay in it), and back.
class InNetns {
 public:
  explicit InNetns(const std::string& ns) {
    original_ = open("/proc/self/ns/net", O_RDONLY | O_CLOEXEC);
    const int target = open(("/var/run/netns/" + ns).c_str(), O_RDONLY | O_CLOEXEC);
    ok_ = original_ >= 0 && target >= 0 && setns(target, CLONE_NEWNET) == 0;
    if (target >= 0) close(target);
  }
  ~InNetns() {
    if (original_ >= 0) {
      if (ok_) setns(original_, CLONE_NEWNET);
      close(original_);
    }
  }
  InNetns(const InNetns&) = delete;
  InNetns& operator=(const InNetns&) = delete;
  bool ok() const { return ok_; }

 private:
  int original_ = -1;
  bool ok_ = false;
};

}  // namespace vloc::testing
