/**
 * @file drilling_display.hpp
 * @brief rviz display `pedicle_drilling/DrillingDisplay`: the bone specimen's three layers as
 *        translucent boxes, the drilled hole, the residual inner cortical layer and a text
 *        overlay with the recognizer's state, drawn in the `bone` tf frame.
 *
 * Inputs: `simulator/ground_truth` (pedicle_drilling/GroundTruth: layer depths, deepest cut,
 * residual, thrust, breakthrough; simulator only, property "Ground truth" off on hardware) and
 * `drilling_state` (pedicle_drilling/DrillingState: state, last key point, averaged force, A*).
 * Every input is optional; a missing or broken one only gives a warning or error in the Displays
 * panel, and the rest is still drawn.
 *
 * From the hardware's own topics, each off while its topic property is empty (the default, so
 * that a configuration saved before them looks as it did), it draws the drilling plan ("Plan
 * topic": `drilling_plan`, pedicle_drilling/DrillingPlan in the tracked marker's frame: the
 * entry, the planned path to the planned depth, the entry tolerance and the depth limit; placed
 * by tf, or by the tracked marker's pose when the marker's frame is not on tf) with the drill
 * tip's advance along it (tf frame "Tip frame"), and writes the breath (`tidal_volume`,
 * `ventilator/breath_source_status`) in its text, with the trial's phase
 * (`compensation/status`). Without the `bone` frame the text hangs at the tracked marker.
 *
 * What it has is published latched on `drilling_display/status` (std_msgs/String) at every
 * change, for scripts and tests: "ground truth: off; drilling state: receiving; plan: shown;
 * ...".
 *
 * It also draws the bone's predicted and tracked marker positions (`compensation/
 * predicted_marker_pose`, `tracker/marker_pose`: the safety monitor's H1 quantity, paired by
 * stamp; magenta and green spheres, their distance in the text) and the drill bit in the detail
 * copy, down to the tip, coloured by the safety monitor's status on `/diagnostics` (green OK,
 * yellow WARN, red ERROR, grey unheard).
 *
 * The specimen is a few centimetres wide and the bit 2.5 mm, which a view of the whole workcell
 * cannot show; the display therefore also draws a magnified "detail" copy of the specimen next
 * to the real one (property "Detail scale", 0 or 1 = off), and puts the text beside it.
 */
#pragma once

#ifndef Q_MOC_RUN
#include <limits>
#include <memory>
#include <string>

#include <ros/ros.h>

#include <OgreQuaternion.h>
#include <OgreVector3.h>

#include <diagnostic_msgs/DiagnosticArray.h>
#include <geometry_msgs/PoseStamped.h>
#include <pedicle_drilling/BreathSourceStatus.h>
#include <pedicle_drilling/DrillingPlan.h>
#include <pedicle_drilling/DrillingState.h>
#include <pedicle_drilling/GroundTruth.h>
#include <pedicle_drilling/TidalVolume.h>
#include <pedicle_drilling/TrialStatus.h>
#include <rviz/display.h>

#include "pedicle_drilling/core/control/trial_view.hpp"
#endif

namespace Ogre {
class SceneNode;
}

namespace rviz {
class BoolProperty;
class ColorProperty;
class FloatProperty;
class MovableText;
class RosTopicProperty;
class StringProperty;
class Shape;
class TfFrameProperty;
class VectorProperty;
}  // namespace rviz

namespace pedicle_drilling {
namespace rviz_plugins {

/** @brief Draws the drilling scene (bone layers, hole, residual, state text) in rviz. */
class DrillingDisplay : public rviz::Display {
  Q_OBJECT

 public:
  /** @brief Creates the properties; the scene is built in onInitialize(). */
  DrillingDisplay();
  /** @brief Unsubscribes and frees the Ogre objects. */
  ~DrillingDisplay() override;

  /** @brief Drops every message and clears the drawing (rviz "Reset"); subscribes anew, so
   *         that the latched ones (plan, breath source, trial phase) come back. */
  void reset() override;
  /** @brief Places the scene at the current pose of the bone frame; redraws on new data. */
  void update(float wall_dt, float ros_dt) override;

 protected:
  /** @brief Creates the Ogre shapes and the text. */
  void onInitialize() override;
  /** @brief Subscribes both topics and shows the scene. */
  void onEnable() override;
  /** @brief Unsubscribes and hides the scene. */
  void onDisable() override;

 private Q_SLOTS:
  void updateTopics();
  void updateAppearance();

 private:
  /** @brief The properties of the hardware's inputs: plan, tip, trial, breath. */
  void createHardwareProperties();
  void subscribe();
  void unsubscribe();
  void groundTruthCallback(const GroundTruth::ConstPtr& msg);
  void drillingStateCallback(const DrillingState::ConstPtr& msg);
  void predictedCallback(const geometry_msgs::PoseStamped::ConstPtr& msg);
  void trackedCallback(const geometry_msgs::PoseStamped::ConstPtr& msg);
  void statusCallback(const TrialStatus::ConstPtr& msg);
  void diagnosticsCallback(const diagnostic_msgs::DiagnosticArray::ConstPtr& msg);
  bool placeMarker(rviz::Shape* sphere, const geometry_msgs::PoseStamped::ConstPtr& msg,
                   const Ogre::Vector3& bone_position, const Ogre::Quaternion& bone_orientation);
  void placeMarkers(const Ogre::Vector3& bone_position, const Ogre::Quaternion& bone_orientation);
  void planCallback(const DrillingPlan::ConstPtr& msg);
  void tidalVolumeCallback(const TidalVolume::ConstPtr& msg);
  void breathSourceCallback(const BreathSourceStatus::ConstPtr& msg);
  /** @brief Where the display's node sits: the bone frame, else the tracked marker, else the
   *         fixed frame's origin (hardware has no bone frame). True with the bone frame. */
  bool placeAnchor(Ogre::Vector3* position, Ogre::Quaternion* orientation);
  /** @brief Draws the plan and measures the tip along it; false when it cannot be placed. */
  bool placePlan(const Ogre::Vector3& anchor_position, const Ogre::Quaternion& anchor_orientation);
  /** @brief The Displays panel's status of each input and the `drilling_display/status` line. */
  void reportInputs();
  bool groundTruthOn() const;
  void rebuild();
  void applyColours();
  std::string overlayText() const;
  std::string planText() const;
  std::string breathText() const;

  /** @brief The five shapes of one copy of the specimen under a common scene node. */
  struct SpecimenVisual {
    Ogre::SceneNode* node = nullptr;
    std::unique_ptr<rviz::Shape> outer_cortical;
    std::unique_ptr<rviz::Shape> cancellous;
    std::unique_ptr<rviz::Shape> inner_cortical;
    std::unique_ptr<rviz::Shape> hole;
    std::unique_ptr<rviz::Shape> residual;
  };
  void createVisual(SpecimenVisual* visual);
  void destroyVisual(SpecimenVisual* visual);

  rviz::BoolProperty* ground_truth_property_;
  rviz::RosTopicProperty* ground_truth_topic_property_;
  rviz::RosTopicProperty* state_topic_property_;
  rviz::TfFrameProperty* frame_property_;
  rviz::FloatProperty* width_property_;
  rviz::FloatProperty* length_property_;
  rviz::ColorProperty* cortical_colour_property_;
  rviz::ColorProperty* cancellous_colour_property_;
  rviz::ColorProperty* hole_colour_property_;
  rviz::ColorProperty* residual_colour_property_;
  rviz::FloatProperty* alpha_property_;
  rviz::BoolProperty* show_text_property_;
  rviz::FloatProperty* text_height_property_;
  rviz::FloatProperty* stale_after_property_;
  rviz::FloatProperty* detail_scale_property_;
  rviz::VectorProperty* detail_offset_property_;
  rviz::RosTopicProperty* predicted_topic_property_;
  rviz::RosTopicProperty* tracked_topic_property_;
  rviz::StringProperty* monitor_status_property_;
  rviz::FloatProperty* marker_size_property_;
  rviz::VectorProperty* text_offset_property_;
  rviz::RosTopicProperty* plan_topic_property_;
  rviz::ColorProperty* plan_colour_property_;
  rviz::FloatProperty* plan_width_property_;
  rviz::TfFrameProperty* tip_frame_property_;
  rviz::RosTopicProperty* trial_status_topic_property_;
  rviz::RosTopicProperty* tidal_volume_topic_property_;
  rviz::RosTopicProperty* breath_source_topic_property_;

  SpecimenVisual true_scale_;
  SpecimenVisual detail_;
  std::unique_ptr<rviz::Shape> predicted_sphere_;
  std::unique_ptr<rviz::Shape> tracked_sphere_;
  std::unique_ptr<rviz::Shape> bit_;             // the drill bit in the detail copy
  std::unique_ptr<rviz::Shape> plan_path_;       // entry to the planned depth
  std::unique_ptr<rviz::Shape> plan_tolerance_;  // the entry +- its tolerance
  std::unique_ptr<rviz::Shape> plan_entry_;
  std::unique_ptr<rviz::Shape> plan_limit_;  // a disc at the planned depth
  Ogre::SceneNode* text_node_ = nullptr;
  rviz::MovableText* text_ = nullptr;

  ros::Subscriber ground_truth_sub_;
  ros::Subscriber state_sub_;
  ros::Subscriber predicted_sub_;
  ros::Subscriber tracked_sub_;
  ros::Subscriber diagnostics_sub_;
  ros::Subscriber status_sub_;
  ros::Subscriber plan_sub_;
  ros::Subscriber tidal_volume_sub_;
  ros::Subscriber breath_source_sub_;
  ros::Publisher summary_pub_;
  std::string last_summary_;
  DrillingPlan::ConstPtr plan_;
  std::string plan_error_;      // why plan_ cannot be drawn ("" = usable)
  std::string plan_placement_;  // how the plan was placed: "tf", "the tracked marker", "" = not
  /// The tip's advance along the plan from its entry and its distance from the plan's axis [m]
  double tip_along_m_ = std::numeric_limits<double>::quiet_NaN();
  double tip_off_axis_m_ = std::numeric_limits<double>::quiet_NaN();
  TidalVolume::ConstPtr tidal_volume_;
  BreathSourceStatus::ConstPtr breath_source_;
  ros::WallTime tidal_volume_received_;
  ros::WallTime tracked_received_;
  ros::WallTime predicted_received_;
  bool tracked_shown_ = false;
  bool predicted_shown_ = false;
  std::string anchor_;  // what the node sits at: "bone", "tracked marker", "origin"
  geometry_msgs::PoseStamped::ConstPtr predicted_;
  geometry_msgs::PoseStamped::ConstPtr tracked_;
  core::TrialView view_;    // pairs prediction and tracker by stamp; the trial's phase
  int monitor_level_ = -1;  // the safety monitor's DiagnosticStatus level, -1 unheard
  bool logged_end_ = false;
  GroundTruth::ConstPtr ground_truth_;
  DrillingState::ConstPtr state_;
  ros::WallTime ground_truth_received_;
  ros::WallTime state_received_;
  std::string layout_error_;
  bool bone_frame_ = false;  // the bone frame is on tf: the specimen can be drawn
  bool dirty_ = true;
};

}  // namespace rviz_plugins
}  // namespace pedicle_drilling
