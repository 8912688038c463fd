/**
 * @file drilling_display.cpp
 * @brief rviz display `pedicle_drilling/DrillingDisplay` (see drilling_display.hpp).
 */
#include "pedicle_drilling/rviz/drilling_display.hpp"

#include <OgreQuaternion.h>
#include <OgreSceneManager.h>
#include <OgreSceneNode.h>
#include <OgreVector3.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include <rviz/display_context.h>
#include <rviz/frame_manager.h>
#include <rviz/ogre_helpers/movable_text.h>
#include <rviz/ogre_helpers/shape.h>
#include <rviz/properties/bool_property.h>
#include <rviz/properties/color_property.h>
#include <rviz/properties/float_property.h>
#include <rviz/properties/ros_topic_property.h>
#include <rviz/properties/status_property.h>
#include <rviz/properties/string_property.h>
#include <rviz/properties/tf_frame_property.h>
#include <rviz/properties/vector_property.h>
#include <std_msgs/String.h>
#include <pluginlib/class_list_macros.hpp>

#include "pedicle_drilling/core/control/depth_limit.hpp"
#include "pedicle_drilling/core/drilling/drilling_scene.hpp"

namespace pedicle_drilling {
namespace rviz_plugins {
namespace {

constexpr float kMinThickness = 1e-5f;  // Ogre dislikes zero scale; 10 um is invisible anyway.

/** @brief Places a unit box between two heights of the bone frame. */
void placeBox(rviz::Shape* box, const core::Slab& slab, float width, float length) {
  box->setPosition(Ogre::Vector3(0.0f, 0.0f, static_cast<float>(slab.centre())));
  box->setScale(
      Ogre::Vector3(width, length, std::max(static_cast<float>(slab.thickness()), kMinThickness)));
  box->getRootNode()->setVisible(slab.thickness() > 0.0);
}

/** @brief Places a unit cylinder (Ogre mesh axis = y) between two heights, axis along z. */
void placeCylinder(rviz::Shape* cylinder, const core::Slab& slab, float diameter) {
  cylinder->setPosition(Ogre::Vector3(0.0f, 0.0f, static_cast<float>(slab.centre())));
  cylinder->setOrientation(Ogre::Quaternion(Ogre::Degree(90.0f), Ogre::Vector3::UNIT_X));
  cylinder->setScale(Ogre::Vector3(
      diameter, std::max(static_cast<float>(slab.thickness()), kMinThickness), diameter));
  cylinder->getRootNode()->setVisible(slab.thickness() > 0.0);
}

/** @brief Places a unit cylinder (Ogre mesh axis = y) from `from` to `to`, `diameter` wide. */
void placeSegment(rviz::Shape* cylinder, const Ogre::Vector3& from, const Ogre::Vector3& to,
                  float diameter) {
  const Ogre::Vector3 axis = to - from;
  const float length = axis.length();
  cylinder->setPosition(0.5f * (from + to));
  cylinder->setOrientation(length > 0.0f ? Ogre::Vector3::UNIT_Y.getRotationTo(axis / length)
                                         : Ogre::Quaternion::IDENTITY);
  cylinder->setScale(Ogre::Vector3(diameter, std::max(length, kMinThickness), diameter));
  cylinder->getRootNode()->setVisible(true);
}

std::string format(const char* fmt, double a) {
  char buffer[128];
  std::snprintf(buffer, sizeof(buffer), fmt, a);
  return buffer;
}

/** @brief "receiving", "stale" or "waiting", as the Displays panel reports an input. */
std::string freshness(bool received, const ros::WallTime& when, double stale_s) {
  if (!received) return "waiting";
  return (ros::WallTime::now() - when).toSec() > stale_s ? "stale" : "receiving";
}

}  // namespace

DrillingDisplay::DrillingDisplay() {
  ground_truth_property_ = new rviz::BoolProperty(
      "Ground truth", true,
      "Draw the specimen's layers, the hole, the residual and the bit from the simulator's ground "
      "truth. Simulator only: off on hardware, where nothing publishes it (the plan, the markers "
      "and the text are drawn either way).",
      this, SLOT(updateTopics()));
  ground_truth_topic_property_ = new rviz::RosTopicProperty(
      "Ground truth topic", "simulator/ground_truth",
      QString::fromStdString(ros::message_traits::datatype<GroundTruth>()),
      "pedicle_drilling/GroundTruth from the simulator: layer depths, deepest cut, residual.", this,
      SLOT(updateTopics()));
  state_topic_property_ = new rviz::RosTopicProperty(
      "Drilling state topic", "drilling_state",
      QString::fromStdString(ros::message_traits::datatype<DrillingState>()),
      "pedicle_drilling/DrillingState from the state recognizer (text overlay).", this,
      SLOT(updateTopics()));
  frame_property_ = new rviz::TfFrameProperty(
      "Bone frame", "bone", "tf frame at the centre of the bone's top surface, +z out of the bone.",
      this, nullptr, false, SLOT(updateAppearance()));
  width_property_ = new rviz::FloatProperty("Bone width (x)", 0.04f,
                                            "Size of the specimen block along x of the bone "
                                            "frame (m).",
                                            this, SLOT(updateAppearance()));
  width_property_->setMin(0.001f);
  width_property_->setMax(1.0f);
  length_property_ = new rviz::FloatProperty("Bone length (y)", 0.03f,
                                             "Size of the specimen block along y of the bone "
                                             "frame (m).",
                                             this, SLOT(updateAppearance()));
  length_property_->setMin(0.001f);
  length_property_->setMax(1.0f);
  cortical_colour_property_ = new rviz::ColorProperty(
      "Cortical colour", QColor(240, 234, 210), "Colour of the outer and inner cortical layers.",
      this, SLOT(updateAppearance()));
  cancellous_colour_property_ =
      new rviz::ColorProperty("Cancellous colour", QColor(214, 140, 110),
                              "Colour of the cancellous layer.", this, SLOT(updateAppearance()));
  hole_colour_property_ = new rviz::ColorProperty("Hole colour", QColor(25, 25, 160),
                                                  "Colour of the drilled hole (2.5 mm bit).", this,
                                                  SLOT(updateAppearance()));
  residual_colour_property_ = new rviz::ColorProperty(
      "Residual colour", QColor(255, 220, 0),
      "Colour of the inner cortical bone left below the hole.", this, SLOT(updateAppearance()));
  alpha_property_ = new rviz::FloatProperty("Alpha", 0.5f,
                                            "Opacity of the bone layers (the hole and the "
                                            "residual are drawn opaque).",
                                            this, SLOT(updateAppearance()));
  alpha_property_->setMin(0.0f);
  alpha_property_->setMax(1.0f);
  show_text_property_ = new rviz::BoolProperty(
      "Show text", true, "Text with state, key point, forces, residual and breakthrough.", this,
      SLOT(updateAppearance()));
  text_height_property_ =
      new rviz::FloatProperty("Text height", 0.02f, "Character height of the text overlay (m).",
                              this, SLOT(updateAppearance()));
  text_height_property_->setMin(0.0005f);
  text_height_property_->setMax(1.0f);
  stale_after_property_ = new rviz::FloatProperty(
      "Stale after (s)", 2.0f, "Warn when no message arrived for this long (wall-clock seconds).",
      this);
  stale_after_property_->setMin(0.1f);
  detail_scale_property_ = new rviz::FloatProperty(
      "Detail scale", 10.0f,
      "Magnification of the detail copy of the specimen drawn beside it (0 or 1: no copy).", this,
      SLOT(updateAppearance()));
  detail_scale_property_->setMin(0.0f);
  detail_scale_property_->setMax(100.0f);
  detail_offset_property_ = new rviz::VectorProperty(
      "Detail offset", Ogre::Vector3(0.3f, 0.0f, 0.42f),
      "Position of the detail copy's top-surface centre in the bone frame (m).", this,
      SLOT(updateAppearance()));
  predicted_topic_property_ = new rviz::RosTopicProperty(
      "Predicted marker topic", "compensation/predicted_marker_pose",
      QString::fromStdString(ros::message_traits::datatype<geometry_msgs::PoseStamped>()),
      "The planner's predicted marker pose at each tracker stamp (magenta sphere).", this,
      SLOT(updateTopics()));
  tracked_topic_property_ = new rviz::RosTopicProperty(
      "Tracked marker topic", "tracker/marker_pose",
      QString::fromStdString(ros::message_traits::datatype<geometry_msgs::PoseStamped>()),
      "The tracker's marker pose (green sphere); predicted - tracked is the H1 quantity.", this,
      SLOT(updateTopics()));
  monitor_status_property_ = new rviz::StringProperty(
      "Monitor status", "/safety_monitor: monitor",
      "Name of the SafetyMonitor's DiagnosticStatus on /diagnostics: colours the drill bit.", this);
  marker_size_property_ = new rviz::FloatProperty(
      "Marker size", 0.012f, "Diameter of the predicted and tracked marker spheres (m).", this,
      SLOT(updateAppearance()));
  marker_size_property_->setMin(0.0005f);
  createHardwareProperties();
}

void DrillingDisplay::createHardwareProperties() {
  text_offset_property_ = new rviz::VectorProperty(
      "Text offset", Ogre::Vector3::ZERO,
      "Moves the text from its place below the specimen (or its detail copy) by this much, in "
      "the bone frame (m): on hardware, out of the way of the drill.",
      this, SLOT(updateAppearance()));
  plan_topic_property_ = new rviz::RosTopicProperty(
      "Plan topic", "", QString::fromStdString(ros::message_traits::datatype<DrillingPlan>()),
      "The drilling plan (latched, in the tracked marker's frame; drilling_plan): entry, planned "
      "path to the planned depth, entry tolerance and depth limit, and the tip along it in the "
      "text. Empty (the default, as before this property): off.",
      this, SLOT(updateTopics()));
  plan_colour_property_ = new rviz::ColorProperty("Plan colour", QColor(0, 230, 230),
                                                  "Colour of the planned path and its entry.", this,
                                                  SLOT(updateAppearance()));
  plan_width_property_ = new rviz::FloatProperty(
      "Plan width", 0.0025f,
      "Diameter of the planned path (m); the entry is twice, the depth-limit disc four times it.",
      this, SLOT(updateAppearance()));
  plan_width_property_->setMin(0.0001f);
  plan_width_property_->setMax(0.1f);
  tip_frame_property_ = new rviz::TfFrameProperty(
      "Tip frame", "drill_tip",
      "tf frame of the drill tip (robot_state_publisher): its advance along the plan in the text.",
      this, nullptr, false, SLOT(updateAppearance()));
  trial_status_topic_property_ = new rviz::RosTopicProperty(
      "Trial status topic", "compensation/status",
      QString::fromStdString(ros::message_traits::datatype<TrialStatus>()),
      "The planner's trial phase (latched): in the text; a new trial starts the H1 pairing afresh.",
      this, SLOT(updateTopics()));
  tidal_volume_topic_property_ = new rviz::RosTopicProperty(
      "Tidal volume topic", "",
      QString::fromStdString(ros::message_traits::datatype<TidalVolume>()),
      "The ventilator's tidal volume and breath phase (tidal_volume: breath index, time in the "
      "breath) in the text. Empty (the default): off.",
      this, SLOT(updateTopics()));
  breath_source_topic_property_ = new rviz::RosTopicProperty(
      "Breath source topic", "",
      QString::fromStdString(ros::message_traits::datatype<BreathSourceStatus>()),
      "Where the Ventilator's breath phase comes from and whether it is usable (latched; "
      "ventilator/breath_source_status) in the text. Empty (the default): off.",
      this, SLOT(updateTopics()));
}

DrillingDisplay::~DrillingDisplay() {
  unsubscribe();
  predicted_sphere_.reset();
  tracked_sphere_.reset();
  bit_.reset();
  plan_path_.reset();
  plan_tolerance_.reset();
  plan_entry_.reset();
  plan_limit_.reset();
  destroyVisual(&true_scale_);
  destroyVisual(&detail_);
  if (text_node_ != nullptr) {
    text_node_->detachAllObjects();
    scene_manager_->destroySceneNode(text_node_);
  }
  delete text_;
}

void DrillingDisplay::onInitialize() {
  frame_property_->setFrameManager(context_->getFrameManager());
  tip_frame_property_->setFrameManager(context_->getFrameManager());
  createVisual(&true_scale_);
  createVisual(&detail_);
  predicted_sphere_ =
      std::make_unique<rviz::Shape>(rviz::Shape::Sphere, scene_manager_, scene_node_);
  tracked_sphere_ = std::make_unique<rviz::Shape>(rviz::Shape::Sphere, scene_manager_, scene_node_);
  predicted_sphere_->setColor(1.0f, 0.2f, 1.0f, 0.9f);
  tracked_sphere_->setColor(0.2f, 1.0f, 0.3f, 0.9f);
  predicted_sphere_->getRootNode()->setVisible(false);
  tracked_sphere_->getRootNode()->setVisible(false);
  bit_ = std::make_unique<rviz::Shape>(rviz::Shape::Cylinder, scene_manager_, detail_.node);
  for (std::unique_ptr<rviz::Shape>* shape : {&plan_path_, &plan_tolerance_, &plan_limit_}) {
    *shape = std::make_unique<rviz::Shape>(rviz::Shape::Cylinder, scene_manager_, scene_node_);
    (*shape)->getRootNode()->setVisible(false);
  }
  plan_entry_ = std::make_unique<rviz::Shape>(rviz::Shape::Sphere, scene_manager_, scene_node_);
  plan_entry_->getRootNode()->setVisible(false);
  summary_pub_ = update_nh_.advertise<std_msgs::String>("drilling_display/status", 1, true);
  text_node_ = scene_node_->createChildSceneNode();
  text_ = new rviz::MovableText("DrillingDisplay");
  text_->setTextAlignment(rviz::MovableText::H_LEFT, rviz::MovableText::V_BELOW);
  text_->showOnTop(true);
  text_node_->attachObject(text_);
  updateAppearance();
}

void DrillingDisplay::createVisual(SpecimenVisual* visual) {
  visual->node = scene_node_->createChildSceneNode();
  visual->outer_cortical =
      std::make_unique<rviz::Shape>(rviz::Shape::Cube, scene_manager_, visual->node);
  visual->cancellous =
      std::make_unique<rviz::Shape>(rviz::Shape::Cube, scene_manager_, visual->node);
  visual->inner_cortical =
      std::make_unique<rviz::Shape>(rviz::Shape::Cube, scene_manager_, visual->node);
  visual->hole = std::make_unique<rviz::Shape>(rviz::Shape::Cylinder, scene_manager_, visual->node);
  visual->residual =
      std::make_unique<rviz::Shape>(rviz::Shape::Cylinder, scene_manager_, visual->node);
}

void DrillingDisplay::destroyVisual(SpecimenVisual* visual) {
  visual->outer_cortical.reset();
  visual->cancellous.reset();
  visual->inner_cortical.reset();
  visual->hole.reset();
  visual->residual.reset();
  if (visual->node != nullptr) {
    scene_manager_->destroySceneNode(visual->node);
    visual->node = nullptr;
  }
}

void DrillingDisplay::onEnable() {
  scene_node_->setVisible(true);
  subscribe();
  dirty_ = true;
}

void DrillingDisplay::onDisable() {
  unsubscribe();
  scene_node_->setVisible(false);
}

void DrillingDisplay::reset() {
  rviz::Display::reset();
  ground_truth_.reset();
  state_.reset();
  predicted_.reset();
  tracked_.reset();
  plan_.reset();
  plan_error_.clear();
  tidal_volume_.reset();
  breath_source_.reset();
  view_.reset();
  monitor_level_ = -1;
  dirty_ = true;
  // The plan, the breath source and the trial's phase are latched: a new subscription brings
  // them back.
  unsubscribe();
  subscribe();
}

void DrillingDisplay::updateTopics() {
  unsubscribe();
  ground_truth_.reset();
  state_.reset();
  plan_.reset();
  plan_error_.clear();
  tidal_volume_.reset();
  breath_source_.reset();
  ground_truth_topic_property_->setHidden(!groundTruthOn());
  if (!groundTruthOn()) {
    deleteStatusStd("Ground truth");
  }
  dirty_ = true;
  if (isEnabled()) {
    subscribe();
  }
}

void DrillingDisplay::updateAppearance() { dirty_ = true; }

bool DrillingDisplay::groundTruthOn() const { return ground_truth_property_->getBool(); }

void DrillingDisplay::subscribe() {
  if (!isEnabled()) {
    return;
  }
  const std::string gt_topic =
      groundTruthOn() ? ground_truth_topic_property_->getTopicStd() : std::string();
  const std::string state_topic = state_topic_property_->getTopicStd();
  try {
    if (!gt_topic.empty()) {
      ground_truth_sub_ =
          update_nh_.subscribe(gt_topic, 5, &DrillingDisplay::groundTruthCallback, this);
    }
    setStatus(rviz::StatusProperty::Ok, "Topic", "subscribed");
  } catch (const ros::Exception& e) {
    setStatus(rviz::StatusProperty::Error, "Topic",
              QString("cannot subscribe to ground truth: ") + e.what());
  }
  try {
    if (!state_topic.empty()) {
      state_sub_ =
          update_nh_.subscribe(state_topic, 5, &DrillingDisplay::drillingStateCallback, this);
    }
  } catch (const ros::Exception& e) {
    setStatus(rviz::StatusProperty::Error, "Topic",
              QString("cannot subscribe to drilling state: ") + e.what());
  }
  try {
    const std::string predicted = predicted_topic_property_->getTopicStd();
    const std::string tracked = tracked_topic_property_->getTopicStd();
    if (!predicted.empty()) {
      predicted_sub_ =
          update_nh_.subscribe(predicted, 20, &DrillingDisplay::predictedCallback, this);
    }
    if (!tracked.empty()) {
      tracked_sub_ = update_nh_.subscribe(tracked, 20, &DrillingDisplay::trackedCallback, this);
    }
    diagnostics_sub_ =
        update_nh_.subscribe("/diagnostics", 20, &DrillingDisplay::diagnosticsCallback, this);
  } catch (const ros::Exception& e) {
    setStatus(rviz::StatusProperty::Error, "Topic",
              QString("cannot subscribe to the marker poses: ") + e.what());
  }
  try {
    const std::string plan = plan_topic_property_->getTopicStd();
    const std::string status = trial_status_topic_property_->getTopicStd();
    const std::string tidal_volume = tidal_volume_topic_property_->getTopicStd();
    const std::string breath_source = breath_source_topic_property_->getTopicStd();
    if (!plan.empty()) {
      plan_sub_ = update_nh_.subscribe(plan, 1, &DrillingDisplay::planCallback, this);
    }
    if (!status.empty()) {
      status_sub_ = update_nh_.subscribe(status, 20, &DrillingDisplay::statusCallback, this);
    }
    if (!tidal_volume.empty()) {
      tidal_volume_sub_ =
          update_nh_.subscribe(tidal_volume, 5, &DrillingDisplay::tidalVolumeCallback, this);
    }
    if (!breath_source.empty()) {
      breath_source_sub_ =
          update_nh_.subscribe(breath_source, 1, &DrillingDisplay::breathSourceCallback, this);
    }
  } catch (const ros::Exception& e) {
    setStatus(rviz::StatusProperty::Error, "Topic",
              QString("cannot subscribe to the plan, the trial or the breath: ") + e.what());
  }
}

void DrillingDisplay::unsubscribe() {
  ground_truth_sub_.shutdown();
  state_sub_.shutdown();
  predicted_sub_.shutdown();
  tracked_sub_.shutdown();
  diagnostics_sub_.shutdown();
  status_sub_.shutdown();
  plan_sub_.shutdown();
  tidal_volume_sub_.shutdown();
  breath_source_sub_.shutdown();
}

void DrillingDisplay::planCallback(const DrillingPlan::ConstPtr& msg) {
  core::DrillingPlan plan;
  plan.frame = msg->header.frame_id;
  plan.entry = Eigen::Vector3d(msg->entry.x, msg->entry.y, msg->entry.z);
  plan.direction = Eigen::Vector3d(msg->direction.x, msg->direction.y, msg->direction.z);
  plan.depth_m = msg->depth_m;
  plan.entry_tolerance_m = msg->entry_tolerance_m;
  plan_error_ = plan.check();
  plan_ = msg;
  dirty_ = true;
}

void DrillingDisplay::tidalVolumeCallback(const TidalVolume::ConstPtr& msg) {
  tidal_volume_ = msg;
  tidal_volume_received_ = ros::WallTime::now();
  dirty_ = true;
}

void DrillingDisplay::breathSourceCallback(const BreathSourceStatus::ConstPtr& msg) {
  breath_source_ = msg;
  dirty_ = true;
}

void DrillingDisplay::statusCallback(const TrialStatus::ConstPtr& msg) {
  view_.onPhase(msg->phase_name, msg->running);  // a new trial starts the view afresh
  dirty_ = true;
}

void DrillingDisplay::predictedCallback(const geometry_msgs::PoseStamped::ConstPtr& msg) {
  predicted_ = msg;
  predicted_received_ = ros::WallTime::now();
  const geometry_msgs::Point& p = msg->pose.position;
  view_.onPredictedMarker(msg->header.stamp.toSec(), Eigen::Vector3d(p.x, p.y, p.z));
  dirty_ = true;
}

void DrillingDisplay::trackedCallback(const geometry_msgs::PoseStamped::ConstPtr& msg) {
  tracked_ = msg;
  tracked_received_ = ros::WallTime::now();
  const geometry_msgs::Point& p = msg->pose.position;
  view_.onTrackedMarker(msg->header.stamp.toSec(), Eigen::Vector3d(p.x, p.y, p.z));
  dirty_ = true;
}

void DrillingDisplay::diagnosticsCallback(const diagnostic_msgs::DiagnosticArray::ConstPtr& msg) {
  for (const diagnostic_msgs::DiagnosticStatus& s : msg->status) {
    if (s.name == monitor_status_property_->getStdString()) {
      monitor_level_ = s.level;  // the monitor's own state: it outlives a trial
      dirty_ = true;
    }
  }
}

bool DrillingDisplay::placeMarker(rviz::Shape* sphere,
                                  const geometry_msgs::PoseStamped::ConstPtr& msg,
                                  const Ogre::Vector3& bone_position,
                                  const Ogre::Quaternion& bone_orientation) {
  Ogre::Vector3 position;
  Ogre::Quaternion orientation;
  if (!msg || !context_->getFrameManager()->transform(msg->header.frame_id, ros::Time(0), msg->pose,
                                                      position, orientation)) {
    sphere->getRootNode()->setVisible(false);
    return false;
  }
  // The spheres hang under the display's node, which sits at the bone frame.
  sphere->setPosition(bone_orientation.Inverse() * (position - bone_position));
  sphere->setScale(Ogre::Vector3(marker_size_property_->getFloat()));
  sphere->getRootNode()->setVisible(true);
  return true;
}

void DrillingDisplay::placeMarkers(const Ogre::Vector3& bone_position,
                                   const Ogre::Quaternion& bone_orientation) {
  predicted_shown_ =
      placeMarker(predicted_sphere_.get(), predicted_, bone_position, bone_orientation);
  tracked_shown_ = placeMarker(tracked_sphere_.get(), tracked_, bone_position, bone_orientation);
}

bool DrillingDisplay::placeAnchor(Ogre::Vector3* position, Ogre::Quaternion* orientation) {
  const std::string frame = frame_property_->getFrameStd();
  if (context_->getFrameManager()->getTransform(frame, ros::Time(0), *position, *orientation)) {
    anchor_ = "bone frame";
    setStatus(rviz::StatusProperty::Ok, "Transform", "ok");
    return true;
  }
  std::string why = "no transform from [" + frame + "] to [" + fixed_frame_.toStdString() + "]";
  if (tracked_ && context_->getFrameManager()->transform(tracked_->header.frame_id, ros::Time(0),
                                                         tracked_->pose, *position, *orientation)) {
    anchor_ = "tracked marker";
    why += ": the text hangs at the tracked marker";
  } else {
    anchor_ = "origin";
    *position = Ogre::Vector3::ZERO;
    *orientation = Ogre::Quaternion::IDENTITY;
    why += ": the text is at the fixed frame's origin";
  }
  // The specimen needs the bone frame; without ground truth (hardware) nothing is missing.
  if (groundTruthOn()) {
    setStatus(rviz::StatusProperty::Error, "Transform",
              QString::fromStdString(why + ", the specimen is hidden"));
  } else {
    setStatus(rviz::StatusProperty::Warn, "Transform", QString::fromStdString(why));
  }
  return false;
}

bool DrillingDisplay::placePlan(const Ogre::Vector3& anchor_position,
                                const Ogre::Quaternion& anchor_orientation) {
  tip_along_m_ = std::numeric_limits<double>::quiet_NaN();
  tip_off_axis_m_ = std::numeric_limits<double>::quiet_NaN();
  plan_placement_.clear();
  for (rviz::Shape* shape :
       {plan_path_.get(), plan_tolerance_.get(), plan_entry_.get(), plan_limit_.get()}) {
    shape->getRootNode()->setVisible(false);
  }
  if (!plan_ || !plan_error_.empty()) return false;
  // The plan's frame (the tracked marker's) in the fixed frame: from tf, else the tracker's pose
  // of that marker (a tracker that publishes a pose topic and no tf).
  Ogre::Vector3 frame_position;
  Ogre::Quaternion frame_orientation;
  auto* frames = context_->getFrameManager();
  if (frames->getTransform(plan_->header.frame_id, ros::Time(0), frame_position,
                           frame_orientation)) {
    plan_placement_ = "tf";
  } else if (tracked_ && frames->transform(tracked_->header.frame_id, ros::Time(0), tracked_->pose,
                                           frame_position, frame_orientation)) {
    plan_placement_ = "the tracked marker";
  } else {
    return false;
  }
  const auto& e = plan_->entry;
  const auto& d = plan_->direction;
  const Ogre::Vector3 entry = frame_position + frame_orientation * Ogre::Vector3(e.x, e.y, e.z);
  const Ogre::Vector3 direction =
      (frame_orientation * Ogre::Vector3(d.x, d.y, d.z)).normalisedCopy();
  const float depth = static_cast<float>(plan_->depth_m);
  const float tolerance = static_cast<float>(plan_->entry_tolerance_m);
  // The shapes hang under the display's node (the anchor): their positions relative to it.
  const Ogre::Quaternion to_local = anchor_orientation.Inverse();
  auto local = [&](const Ogre::Vector3& p) { return to_local * (p - anchor_position); };
  const float width = plan_width_property_->getFloat();
  placeSegment(plan_path_.get(), local(entry), local(entry + depth * direction), width);
  if (tolerance > 0.0f) {
    placeSegment(plan_tolerance_.get(), local(entry - tolerance * direction),
                 local(entry + tolerance * direction), 2.0f * width);
  }
  plan_entry_->setPosition(local(entry));
  plan_entry_->setScale(Ogre::Vector3(2.0f * width));
  plan_entry_->getRootNode()->setVisible(true);
  placeSegment(plan_limit_.get(), local(entry + (depth - 0.1f * width) * direction),
               local(entry + (depth + 0.1f * width) * direction), 4.0f * width);
  // The drill tip along the plan (robot_state_publisher's drill_tip): how far it advanced from
  // the planned entry and how far it is off the planned axis.
  Ogre::Vector3 tip;
  Ogre::Quaternion tip_orientation;
  const std::string tip_frame = tip_frame_property_->getFrameStd();
  if (!tip_frame.empty() && frames->getTransform(tip_frame, ros::Time(0), tip, tip_orientation)) {
    const Ogre::Vector3 from_entry = tip - entry;
    const float along = from_entry.dotProduct(direction);
    tip_along_m_ = along;
    tip_off_axis_m_ = (from_entry - along * direction).length();
  }
  return true;
}

void DrillingDisplay::groundTruthCallback(const GroundTruth::ConstPtr& msg) {
  ground_truth_ = msg;
  ground_truth_received_ = ros::WallTime::now();
  dirty_ = true;
}

void DrillingDisplay::drillingStateCallback(const DrillingState::ConstPtr& msg) {
  state_ = msg;
  state_received_ = ros::WallTime::now();
  dirty_ = true;
}

void DrillingDisplay::update(float /*wall_dt*/, float /*ros_dt*/) {
  Ogre::Vector3 position;
  Ogre::Quaternion orientation;
  const bool bone_frame = placeAnchor(&position, &orientation);
  if (bone_frame != bone_frame_) {
    bone_frame_ = bone_frame;
    dirty_ = true;  // the specimen is drawn in the bone frame only
  }
  scene_node_->setPosition(position);
  scene_node_->setOrientation(orientation);
  placeMarkers(position, orientation);
  placePlan(position, orientation);
  reportInputs();
  if (dirty_) {
    rebuild();
    dirty_ = false;
  }
}

void DrillingDisplay::reportInputs() {
  const double stale_s = stale_after_property_->getFloat();
  const ros::WallTime now = ros::WallTime::now();
  auto report = [&](const char* name, bool received, const ros::WallTime& when,
                    const std::string& topic) {
    if (!received) {
      setStatus(rviz::StatusProperty::Warn, name,
                QString::fromStdString("no message received on [" + topic + "]"));
    } else if ((now - when).toSec() > stale_s) {
      setStatus(rviz::StatusProperty::Warn, name,
                QString::fromStdString("last message on [" + topic + "] " +
                                       format("%.1f s ago", (now - when).toSec())));
    } else {
      setStatus(rviz::StatusProperty::Ok, name, "receiving");
    }
  };
  if (groundTruthOn() && layout_error_.empty()) {
    report("Ground truth", static_cast<bool>(ground_truth_), ground_truth_received_,
           ground_truth_topic_property_->getTopicStd());
  }
  report("Drilling state", static_cast<bool>(state_), state_received_,
         state_topic_property_->getTopicStd());
  report("Tracked marker", static_cast<bool>(tracked_), tracked_received_,
         tracked_topic_property_->getTopicStd());
  // The planner predicts during a trial only: silence is no warning.
  setStatus(
      rviz::StatusProperty::Ok, "Predicted marker",
      QString::fromStdString(
          (predicted_ ? "last message " + format("%.1f s ago", (now - predicted_received_).toSec())
                      : std::string("none yet")) +
          " on [" + predicted_topic_property_->getTopicStd() +
          "] (the planner predicts during a trial)"));
  const std::string tidal_volume_topic = tidal_volume_topic_property_->getTopicStd();
  if (tidal_volume_topic.empty()) {
    deleteStatusStd("Tidal volume");
  } else {
    report("Tidal volume", static_cast<bool>(tidal_volume_), tidal_volume_received_,
           tidal_volume_topic);
  }
  // The plan is latched: one message, no staleness.
  const std::string plan_topic = plan_topic_property_->getTopicStd();
  std::string plan = "shown";
  if (plan_topic.empty()) {
    plan = "off";
    deleteStatusStd("Plan");
  } else if (!plan_) {
    plan = "waiting";
    setStatus(rviz::StatusProperty::Warn, "Plan",
              QString::fromStdString("no message received on [" + plan_topic + "]"));
  } else if (!plan_error_.empty()) {
    plan = "invalid";
    setStatus(rviz::StatusProperty::Error, "Plan",
              QString::fromStdString("invalid plan on [" + plan_topic + "]: " + plan_error_));
  } else if (plan_placement_.empty()) {
    plan = "no transform";
    setStatus(rviz::StatusProperty::Warn, "Plan",
              QString::fromStdString("no transform from the plan's frame [" +
                                     plan_->header.frame_id + "] and no tracked marker pose"));
  } else {
    plan = "shown by " + plan_placement_;
    setStatus(rviz::StatusProperty::Ok, "Plan",
              QString::fromStdString("in [" + plan_->header.frame_id + "], placed by " +
                                     plan_placement_));
  }

  // The summary for scripts and tests: states only, so that it changes with them.
  std::string gt = "off";
  if (groundTruthOn()) {
    gt = layout_error_.empty()
             ? freshness(static_cast<bool>(ground_truth_), ground_truth_received_, stale_s)
             : "invalid";
  }
  auto shown = [](bool received, bool placed) {
    return std::string(!received ? "waiting" : placed ? "shown" : "no transform");
  };
  const std::string summary =
      "ground truth: " + gt +
      "; drilling state: " + freshness(static_cast<bool>(state_), state_received_, stale_s) +
      "; plan: " + plan +
      "; tracked marker: " + shown(static_cast<bool>(tracked_), tracked_shown_) +
      "; predicted marker: " + shown(static_cast<bool>(predicted_), predicted_shown_) +
      "; tidal volume: " +
      (tidal_volume_topic.empty()
           ? std::string("off")
           : freshness(static_cast<bool>(tidal_volume_), tidal_volume_received_, stale_s)) +
      "; trial: " + (view_.phase().empty() ? std::string("waiting") : view_.phase()) +
      "; anchor: " + anchor_;
  if (summary != last_summary_ && summary_pub_) {
    last_summary_ = summary;
    std_msgs::String msg;
    msg.data = summary;
    summary_pub_.publish(msg);
  }
}

void DrillingDisplay::applyColours() {
  const float alpha = alpha_property_->getFloat();
  const Ogre::ColourValue cortical = cortical_colour_property_->getOgreColor();
  const Ogre::ColourValue cancellous = cancellous_colour_property_->getOgreColor();
  const Ogre::ColourValue hole = hole_colour_property_->getOgreColor();
  const Ogre::ColourValue residual = residual_colour_property_->getOgreColor();
  for (SpecimenVisual* visual : {&true_scale_, &detail_}) {
    visual->outer_cortical->setColor(cortical.r, cortical.g, cortical.b, alpha);
    visual->inner_cortical->setColor(cortical.r, cortical.g, cortical.b, alpha);
    visual->cancellous->setColor(cancellous.r, cancellous.g, cancellous.b, alpha);
    visual->hole->setColor(hole.r, hole.g, hole.b, 1.0f);
    visual->residual->setColor(residual.r, residual.g, residual.b, 1.0f);
  }
  const Ogre::ColourValue plan = plan_colour_property_->getOgreColor();
  plan_path_->setColor(plan.r, plan.g, plan.b, 0.9f);
  plan_entry_->setColor(plan.r, plan.g, plan.b, 1.0f);
  plan_tolerance_->setColor(plan.r, plan.g, plan.b, 0.3f);
  // The depth limit: the plan's colour, darker (the plan's end, never passed).
  plan_limit_->setColor(0.5f * plan.r, 0.5f * plan.g, 0.5f * plan.b, 1.0f);
}

void DrillingDisplay::rebuild() {
  applyColours();
  const float width = width_property_->getFloat();
  const float length = length_property_->getFloat();
  constexpr float kBitDiameter = 0.0025f;  // paper Sec. V-A

  layout_error_.clear();
  core::DrillingScene scene;
  bool drawn = false;
  if (ground_truth_ && groundTruthOn()) {
    core::SpecimenDepths depths;
    depths.outer_cortical_end_m = ground_truth_->outer_cortical_end_m;
    depths.inner_cortical_start_m = ground_truth_->inner_cortical_start_m;
    depths.inner_cortical_end_m = ground_truth_->inner_cortical_end_m;
    depths.max_depth_cut_m = ground_truth_->max_depth_cut_m;
    depths.residual_inner_cortical_m = ground_truth_->residual_inner_cortical_m;
    try {
      scene = core::layoutDrillingScene(depths);
      drawn = true;
    } catch (const std::invalid_argument& e) {
      layout_error_ = e.what();
      setStatus(rviz::StatusProperty::Error, "Ground truth",
                QString::fromStdString("invalid message: " + layout_error_));
    }
  }
  const float detail_scale = detail_scale_property_->getFloat();
  const bool detail_on = detail_scale > 1.0f;
  const Ogre::Vector3 detail_offset = detail_offset_property_->getVector();
  // The specimen only in the bone frame: without it the node sits at the tracked marker.
  drawn = drawn && bone_frame_ && groundTruthOn();
  // SceneNode::setVisible() cascades to the shapes, so set it first and hide shapes after.
  true_scale_.node->setVisible(drawn);
  detail_.node->setVisible(drawn && detail_on);
  if (drawn) {
    for (SpecimenVisual* visual : {&true_scale_, &detail_}) {
      placeBox(visual->outer_cortical.get(), scene.outer_cortical, width, length);
      placeBox(visual->cancellous.get(), scene.cancellous, width, length);
      placeBox(visual->inner_cortical.get(), scene.inner_cortical, width, length);
      placeCylinder(visual->hole.get(), scene.hole, kBitDiameter);
      // The residual is highlighted as a disc twice as wide as the bit, below the hole.
      placeCylinder(visual->residual.get(), scene.residual, 2.0f * kBitDiameter);
      if (visual == &detail_ && !detail_on) {
        visual->node->setVisible(false);
      }
    }
  }
  detail_.node->setPosition(detail_offset);
  detail_.node->setScale(Ogre::Vector3(detail_on ? detail_scale : 1.0f));
  // The bit in the detail copy: from 5 mm above the surface down to the tip, coloured by the
  // safety monitor's status.
  if (drawn && ground_truth_ && std::isfinite(ground_truth_->tip_depth_m)) {
    core::Slab bit;
    bit.top_z_m = 0.005;
    bit.bottom_z_m = -ground_truth_->tip_depth_m;
    placeCylinder(bit_.get(), bit, 1.1f * kBitDiameter);  // over the hole it cut
    const int level = monitor_level_;
    if (level == 0) {
      bit_->setColor(0.2f, 0.85f, 0.2f, 1.0f);
    } else if (level == 1) {
      bit_->setColor(1.0f, 0.85f, 0.1f, 1.0f);
    } else if (level >= 2) {
      bit_->setColor(1.0f, 0.15f, 0.15f, 1.0f);
    } else {
      bit_->setColor(0.6f, 0.6f, 0.6f, 1.0f);
    }
  }
  // The residual, once the trial ended (compensation/status done or failed).
  const bool ended = view_.ended() && ground_truth_ && groundTruthOn() && layout_error_.empty();
  if (ended && !logged_end_) {
    ROS_INFO("DrillingDisplay: trial %s, residual shown: %.2f mm, breakthrough %s",
             view_.phase().c_str(), 1e3 * ground_truth_->residual_inner_cortical_m,
             ground_truth_->breakthrough ? "yes" : "no");
  }
  logged_end_ = ended;

  // Text: below the detail copy (or the specimen itself), starting at its left (-x) edge.
  const float text_height = text_height_property_->getFloat();
  // Without ground truth (hardware) there is no detail copy: the text hangs at the anchor.
  const bool detail_text = detail_on && groundTruthOn();
  const float scale = detail_text ? detail_scale : 1.0f;
  const Ogre::Vector3 anchor = detail_text ? detail_offset : Ogre::Vector3::ZERO;
  const float depth = drawn ? static_cast<float>(-scene.inner_cortical.bottom_z_m) : 0.01f;
  text_->setCharacterHeight(text_height);
  text_->setCaption(overlayText());
  text_->setColor(Ogre::ColourValue(1.0f, 1.0f, 1.0f, 1.0f));
  text_node_->setPosition(
      anchor + Ogre::Vector3(-0.5f * width * scale, 0.0f, -depth * scale - 1.5f * text_height) +
      text_offset_property_->getVector());
  text_node_->setVisible(show_text_property_->getBool());
}

std::string DrillingDisplay::overlayText() const {
  std::string text;
  if (state_) {
    text += "state: " +
            (state_->state_name.empty() ? std::to_string(state_->state) : state_->state_name);
    if (state_->stop) {
      text += "  STOP";
    }
    text += state_->last_key_point > 0
                ? "\nlast key point: " + std::to_string(state_->last_key_point)
                : std::string("\nlast key point: none");
    text += "\n" + format("averaged force: %.2f N", state_->averaged_force) +
            format("   A*: %.3f", state_->feature);
  } else {
    text += "state: no message on " + state_topic_property_->getTopicStd();
  }
  if (!groundTruthOn()) {
    // hardware: no ground truth lines
  } else if (!ground_truth_) {
    text += "\nground truth: no message on " + ground_truth_topic_property_->getTopicStd();
  } else if (!layout_error_.empty()) {
    text += "\nground truth invalid: " + layout_error_;
  } else {
    text += "\n" + format("thrust: %.2f N", ground_truth_->thrust_n) + "\n" +
            format("left to the canal wall: %.2f mm",
                   1000.0 * ground_truth_->residual_inner_cortical_m) +
            "\nbreakthrough: " + (ground_truth_->breakthrough ? "YES" : "no");
  }
  if (std::isfinite(view_.positionError())) {
    text += format("\nbone predicted - tracked: %.2f mm (H1 1.2 mm)", 1e3 * view_.positionError());
  }
  static const char* const kLevels[] = {"OK", "WARN", "ERROR", "STALE"};
  const int level = monitor_level_;
  text +=
      std::string("\nsafety monitor: ") + (level >= 0 && level <= 3 ? kLevels[level] : "not heard");
  text += "\ntrial: " + (view_.phase().empty()
                             ? "no message on " + trial_status_topic_property_->getTopicStd()
                             : view_.phase());
  text += planText() + breathText();
  return text;
}

std::string DrillingDisplay::planText() const {
  const std::string topic = plan_topic_property_->getTopicStd();
  if (topic.empty()) return "";
  if (!plan_) return "\nplan: no message on " + topic;
  if (!plan_error_.empty()) return "\nplan invalid: " + plan_error_;
  std::string text = format("\nplan: %.2f mm deep", 1e3 * plan_->depth_m) +
                     format(", entry tolerance %.2f mm", 1e3 * plan_->entry_tolerance_m);
  if (plan_placement_.empty()) {
    text += " (no transform from [" + plan_->header.frame_id + "])";
  } else if (std::isfinite(tip_along_m_)) {
    text += format("\ntip: %.2f", 1e3 * tip_along_m_) +
            format(" of %.2f mm along the plan,", 1e3 * plan_->depth_m) +
            format(" %.2f mm off it", 1e3 * tip_off_axis_m_);
  }
  return text;
}

std::string DrillingDisplay::breathText() const {
  std::string text;
  const std::string topic = tidal_volume_topic_property_->getTopicStd();
  if (topic.empty()) {
    // off
  } else if (!tidal_volume_) {
    text = "\nbreath: no message on " + topic;
  } else {
    text = "\nbreath " + std::to_string(tidal_volume_->breath_index) +
           format(": %.2f s in", tidal_volume_->time_in_breath_s) +
           format(", %.0f ml", tidal_volume_->volume_ml);
  }
  if (breath_source_ && !breath_source_topic_property_->getTopicStd().empty()) {
    text += "\nbreath source: " + breath_source_->source +
            (breath_source_->ready ? std::string(", ready") : ": " + breath_source_->message);
  }
  return text;
}

}  // namespace rviz_plugins
}  // namespace pedicle_drilling

PLUGINLIB_EXPORT_CLASS(pedicle_drilling::rviz_plugins::DrillingDisplay, rviz::Display)
