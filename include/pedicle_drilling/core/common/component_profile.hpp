/**
 * @file component_profile.hpp
 * @brief Where a trial's wall time goes: the core engine's own profile, by
 *        component, accumulated while profiling is on (trial_engine --profile, campaign
 *        --profile, make bench). Off, nothing is timed: no clock is read.
 */
#pragma once

#include <array>
#include <chrono>
#include <cstdint>

namespace pedicle_drilling::core {

/** @brief The parts of a trial the profile times. */
enum class Component : int {
  kArmControllers,  ///< per arm block: the controllers' trajectories, the feed drive, setpoints
  kArmStep,         ///< the arm's dynamics step (BulletArm::step: the servo and Bullet's world)
  kBulletWorld,     ///< of kArmStep, Bullet's own world step (the articulated-body algorithm)
  kPatient,         ///< the ventilator and the breath sensor
  kPlatform,        ///< the SPMS: the patient's inverse and the platform's forward kinematics
  kDrilling,        ///< the drilling force law and the elastic contact
  kSensor,          ///< the F/T sensor chain and the tare
  kRecognizer,      ///< the drilling-state recognizer (every force sample)
  kMonitor,         ///< the safety monitor (every force sample and check)
  kEngineStep,      ///< one whole engine step: all of the above and the rest of the pipeline
  kCount
};

/** @brief Wall time by component, the simulated time and the trials it covers. */
class ComponentProfile {
 public:
  using Clock = std::chrono::steady_clock;

  /** @brief Adds @p d of wall time to @p c. */
  void add(Component c, Clock::duration d) { ns_[index(c)] += d.count(); }
  /** @brief Wall seconds spent in @p c. */
  double seconds(Component c) const {
    return std::chrono::duration<double>(Clock::duration(ns_[index(c)])).count();
  }
  /** @brief One more trial of @p sim_s simulated seconds. */
  void addTrial(double sim_s) {
    ++trials_;
    sim_s_ += sim_s;
  }
  /** @brief Trials covered. */
  std::uint64_t trials() const { return trials_; }
  /** @brief Simulated seconds covered. */
  double simSeconds() const { return sim_s_; }
  /** @brief The component's name in reports (snake case). */
  static const char* name(Component c) {
    static constexpr std::array<const char*, static_cast<std::size_t>(Component::kCount)> names{
        "arm_controllers", "arm_step", "bullet_world", "patient", "platform",
        "drilling",        "sensor",   "recognizer",   "monitor", "engine_step"};
    return names[index(c)];
  }

 private:
  static std::size_t index(Component c) { return static_cast<std::size_t>(c); }
  std::array<Clock::rep, static_cast<std::size_t>(Component::kCount)> ns_{};
  std::uint64_t trials_ = 0;
  double sim_s_ = 0.0;
};

/** @brief Times its scope into a profile's component; does nothing with no profile. */
class ScopedComponentTimer {
 public:
  /** @brief Starts timing @p c into @p profile (nullptr: off). */
  ScopedComponentTimer(ComponentProfile* profile, Component c) : profile_(profile), c_(c) {
    if (profile_) start_ = ComponentProfile::Clock::now();
  }
  ~ScopedComponentTimer() {
    if (profile_) profile_->add(c_, ComponentProfile::Clock::now() - start_);
  }
  ScopedComponentTimer(const ScopedComponentTimer&) = delete;
  ScopedComponentTimer& operator=(const ScopedComponentTimer&) = delete;

 private:
  ComponentProfile* profile_;
  Component c_;
  ComponentProfile::Clock::time_point start_{};
};

/** @brief Times consecutive sections: mark(c) adds the time since the last mark to c. */
class ComponentLaps {
 public:
  /** @brief Starts the first section (nullptr: off, no clock read). */
  explicit ComponentLaps(ComponentProfile* profile) : profile_(profile) { restart(); }
  /** @brief The time since the last mark (or restart) goes to @p c; the next section starts. */
  void mark(Component c) {
    if (!profile_) return;
    const ComponentProfile::Clock::time_point now = ComponentProfile::Clock::now();
    profile_->add(c, now - last_);
    last_ = now;
  }
  /** @brief The next section starts now (the time since the last mark is not counted). */
  void restart() {
    if (profile_) last_ = ComponentProfile::Clock::now();
  }

 private:
  ComponentProfile* profile_;
  ComponentProfile::Clock::time_point last_{};
};

}  // namespace pedicle_drilling::core
