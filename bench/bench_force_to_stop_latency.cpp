// Benchmark: force-sample-to-stop-command latency through a nodelet manager.
//
// The StateRecognizer nodelet is loaded in-process with nodelet::Loader (as in a nodelet
// manager: zero-copy intra-process messages, the manager's worker threads). A synthetic two-layer
// thrust profile (1 kHz stamps) is published on ft_sensor/wrench up to the sample before the one
// at which the recognizer stops (found offline with the same core), the queue is drained, then the
// stop-triggering sample is published and the time until drill/stop arrives is measured. Repeated
// over many trials (~reset between them). Prints
//   BENCH force_to_stop_latency_p50 <us> us
//   BENCH force_to_stop_latency_p99 <us> us
// Needs no running ROS master: it starts its own rosmaster on a private port.
#include <geometry_msgs/WrenchStamped.h>
#include <nodelet/loader.h>
#include <ros/ros.h>
#include <signal.h>
#include <std_srvs/Trigger.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "pedicle_drilling/StopCommand.h"
#include "pedicle_drilling/core/drilling/state_recognizer.hpp"

namespace {

using Clock = std::chrono::steady_clock;

double cleanForce(double t) {
  if (t < 2.0) return 0.0;
  if (t < 4.0) return 1.5 * (t - 2.0);
  if (t < 5.0) return 3.0;
  if (t < 6.0) return 3.0 - 2.3 * (t - 5.0);
  if (t < 16.0) return 0.7;
  if (t < 18.0) return 0.7 + 1.15 * (t - 16.0);
  if (t < 19.5) return 3.0;
  return 0.1;
}

std::atomic<bool> g_stop_received{false};
std::atomic<long long> g_stop_ns{0};

void onStop(const pedicle_drilling::StopCommand::ConstPtr& /*msg*/) {
  g_stop_ns =
      std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now().time_since_epoch()).count();
  g_stop_received = true;
}

pid_t startMaster(int port) {
  const pid_t pid = fork();
  if (pid == 0) {
    const std::string p = std::to_string(port);
    // Quiet master; its log goes to ROS_LOG_DIR or ~/.ros.
    if (std::freopen("/dev/null", "w", stdout) == nullptr) _exit(127);
    if (std::freopen("/dev/null", "w", stderr) == nullptr) _exit(127);
    execlp("rosmaster", "rosmaster", "--core", "-p", p.c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  return pid;
}

}  // namespace

int main(int argc, char** argv) {
  const int port = 20000 + static_cast<int>(getpid() % 20000);
  const std::string uri = "http://127.0.0.1:" + std::to_string(port);
  setenv("ROS_MASTER_URI", uri.c_str(), 1);
  const pid_t master = startMaster(port);
  if (master < 0) {
    std::fprintf(stderr, "cannot start rosmaster\n");
    return 1;
  }
  int status = 1;
  {
    ros::init(argc, argv, "bench_force_to_stop_latency", ros::init_options::NoSigintHandler);
    for (int i = 0; i < 200 && !ros::master::check(); ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    if (!ros::master::check()) {
      std::fprintf(stderr, "rosmaster did not come up on %s\n", uri.c_str());
      kill(master, SIGTERM);
      waitpid(master, nullptr, 0);
      return 1;
    }
    ros::NodeHandle nh;
    ros::AsyncSpinner spinner(1);
    spinner.start();
    nodelet::Loader loader(false);
    const std::map<std::string, std::string> remappings;
    const std::vector<std::string> nodelet_argv;
    if (!loader.load("/state_recognizer", "pedicle_drilling/StateRecognizer", remappings,
                     nodelet_argv)) {
      std::fprintf(stderr, "cannot load pedicle_drilling/StateRecognizer\n");
    } else {
      ros::Publisher pub = nh.advertise<geometry_msgs::WrenchStamped>("ft_sensor/wrench", 5000);
      ros::Subscriber sub =
          nh.subscribe("drill/stop", 10, onStop, ros::TransportHints().tcpNoDelay());
      for (int i = 0; i < 200 && (pub.getNumSubscribers() == 0 || sub.getNumPublishers() == 0);
           ++i) {
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
      }
      // Profile and the sample at which the recognizer (same defaults) stops.
      std::vector<double> force(23000);
      std::mt19937 rng(7);
      std::normal_distribution<double> noise(0.0, 0.05);
      for (std::size_t i = 0; i < force.size(); ++i) force[i] = cleanForce(i * 1e-3) + noise(rng);
      pedicle_drilling::core::StateRecognizer offline;
      std::size_t stop_index = force.size();
      for (std::size_t i = 0; i < force.size(); ++i) {
        if (offline.push(i * 1e-3, force[i]).stop) {
          stop_index = i;
          break;
        }
      }
      auto publishSample = [&pub, &force](std::size_t i) {
        geometry_msgs::WrenchStamped::Ptr msg(new geometry_msgs::WrenchStamped);
        msg->header.stamp = ros::Time(100.0 + i * 1e-3);
        msg->wrench.force.z = force[i];
        pub.publish(msg);
      };
      std::vector<double> latencies_us;
      int mismatches = 0;
      const int kTrials = 60;
      for (int trial = 0; trial < kTrials && stop_index < force.size(); ++trial) {
        std_srvs::Trigger reset;
        if (!ros::service::call("/state_recognizer/reset", reset)) break;
        g_stop_received = false;
        for (std::size_t i = 0; i < stop_index; ++i) {
          publishSample(i);
          if (i % 50 == 49) std::this_thread::sleep_for(std::chrono::microseconds(500));
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(30));  // drain the queue
        if (g_stop_received) {  // stopped early: a sample was dropped, the trial is invalid
          ++mismatches;
          continue;
        }
        const auto t0 = Clock::now();
        publishSample(stop_index);
        while (!g_stop_received && Clock::now() - t0 < std::chrono::seconds(1)) {
          std::this_thread::yield();
        }
        if (!g_stop_received) {
          ++mismatches;
          continue;
        }
        const long long t0_ns =
            std::chrono::duration_cast<std::chrono::nanoseconds>(t0.time_since_epoch()).count();
        latencies_us.push_back((g_stop_ns - t0_ns) * 1e-3);
      }
      std::sort(latencies_us.begin(), latencies_us.end());
      if (!latencies_us.empty()) {
        auto pct = [&latencies_us](double p) {
          const std::size_t i = std::min(
              latencies_us.size() - 1,
              static_cast<std::size_t>(p * static_cast<double>(latencies_us.size() - 1) + 0.5));
          return latencies_us[i];
        };
        std::printf("# %zu trials (%d invalid), stop at raw sample %zu, in-process nodelet\n",
                    latencies_us.size(), mismatches, stop_index);
        std::printf("BENCH force_to_stop_latency_p50 %.1f us\n", pct(0.50));
        std::printf("BENCH force_to_stop_latency_p99 %.1f us\n", pct(0.99));
        status = 0;
      } else {
        std::fprintf(stderr, "no valid trial (stop index %zu, %d invalid)\n", stop_index,
                     mismatches);
      }
    }
    spinner.stop();
    loader.clear();
    ros::shutdown();
  }
  kill(master, SIGTERM);
  waitpid(master, nullptr, 0);
  return status;
}
