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
#include <pluginlib/class_list_macros.hpp>

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

std::string format(const char* fmt, double a) {
  char buffer[128];
  std::snprintf(buffer, sizeof(buffer), fmt, a);
  return buffer;
}

}  // namespace

DrillingDisplay::DrillingDisplay() {
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
}

DrillingDisplay::~DrillingDisplay() {
  unsubscribe();
  predicted_sphere_.reset();
  tracked_sphere_.reset();
  bit_.reset();
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
  view_.reset();
  monitor_level_ = -1;
  dirty_ = true;
}

void DrillingDisplay::updateTopics() {
  unsubscribe();
  ground_truth_.reset();
  state_.reset();
  dirty_ = true;
  if (isEnabled()) {
    subscribe();
  }
}

void DrillingDisplay::updateAppearance() { dirty_ = true; }

void DrillingDisplay::subscribe() {
  if (!isEnabled()) {
    return;
  }
  const std::string gt_topic = ground_truth_topic_property_->getTopicStd();
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
    status_sub_ =
        update_nh_.subscribe("compensation/status", 20, &DrillingDisplay::statusCallback, this);
  } catch (const ros::Exception& e) {
    setStatus(rviz::StatusProperty::Error, "Topic",
              QString("cannot subscribe to the marker poses: ") + e.what());
  }
}

void DrillingDisplay::unsubscribe() {
  ground_truth_sub_.shutdown();
  state_sub_.shutdown();
  predicted_sub_.shutdown();
  tracked_sub_.shutdown();
  diagnostics_sub_.shutdown();
  status_sub_.shutdown();
}

void DrillingDisplay::statusCallback(const TrialStatus::ConstPtr& msg) {
  view_.onPhase(msg->phase_name, msg->running);  // a new trial starts the view afresh
  dirty_ = true;
}

void DrillingDisplay::predictedCallback(const geometry_msgs::PoseStamped::ConstPtr& msg) {
  predicted_ = msg;
  const geometry_msgs::Point& p = msg->pose.position;
  view_.onPredictedMarker(msg->header.stamp.toSec(), Eigen::Vector3d(p.x, p.y, p.z));
  dirty_ = true;
}

void DrillingDisplay::trackedCallback(const geometry_msgs::PoseStamped::ConstPtr& msg) {
  tracked_ = msg;
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
  placeMarker(predicted_sphere_.get(), predicted_, bone_position, bone_orientation);
  placeMarker(tracked_sphere_.get(), tracked_, bone_position, bone_orientation);
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
  const std::string frame = frame_property_->getFrameStd();
  Ogre::Vector3 position;
  Ogre::Quaternion orientation;
  if (context_->getFrameManager()->getTransform(frame, ros::Time(0), position, orientation)) {
    scene_node_->setPosition(position);
    scene_node_->setOrientation(orientation);
    placeMarkers(position, orientation);
    setStatus(rviz::StatusProperty::Ok, "Transform", "ok");
  } else {
    setStatus(rviz::StatusProperty::Error, "Transform",
              QString::fromStdString("no transform from [" + frame + "] to [" +
                                     fixed_frame_.toStdString() + "]"));
  }

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
  if (layout_error_.empty()) {
    report("Ground truth", static_cast<bool>(ground_truth_), ground_truth_received_,
           ground_truth_topic_property_->getTopicStd());
  }
  report("Drilling state", static_cast<bool>(state_), state_received_,
         state_topic_property_->getTopicStd());

  if (dirty_) {
    rebuild();
    dirty_ = false;
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
}

void DrillingDisplay::rebuild() {
  applyColours();
  const float width = width_property_->getFloat();
  const float length = length_property_->getFloat();
  constexpr float kBitDiameter = 0.0025f;  // paper Sec. V-A

  layout_error_.clear();
  core::DrillingScene scene;
  bool drawn = false;
  if (ground_truth_) {
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
  const bool ended = view_.ended() && ground_truth_ && layout_error_.empty();
  if (ended && !logged_end_) {
    ROS_INFO("DrillingDisplay: trial %s, residual shown: %.2f mm, breakthrough %s",
             view_.phase().c_str(), 1e3 * ground_truth_->residual_inner_cortical_m,
             ground_truth_->breakthrough ? "yes" : "no");
  }
  logged_end_ = ended;

  // Text: below the detail copy (or the specimen itself), starting at its left (-x) edge.
  const float text_height = text_height_property_->getFloat();
  const float scale = detail_on ? detail_scale : 1.0f;
  const Ogre::Vector3 anchor = detail_on ? detail_offset : Ogre::Vector3::ZERO;
  const float depth = drawn ? static_cast<float>(-scene.inner_cortical.bottom_z_m) : 0.01f;
  text_->setCharacterHeight(text_height);
  text_->setCaption(overlayText());
  text_->setColor(Ogre::ColourValue(1.0f, 1.0f, 1.0f, 1.0f));
  text_node_->setPosition(
      anchor + Ogre::Vector3(-0.5f * width * scale, 0.0f, -depth * scale - 1.5f * text_height));
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
  text += "\n";
  if (!ground_truth_) {
    text += "ground truth: no message on " + ground_truth_topic_property_->getTopicStd();
  } else if (!layout_error_.empty()) {
    text += "ground truth invalid: " + layout_error_;
  } else {
    text += format("thrust: %.2f N", ground_truth_->thrust_n) + "\n" +
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
  return text;
}

}  // namespace rviz_plugins
}  // namespace pedicle_drilling

PLUGINLIB_EXPORT_CLASS(pedicle_drilling::rviz_plugins::DrillingDisplay, rviz::Display)
