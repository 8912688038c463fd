/**
 * @file drilling_display.hpp
 * @brief rviz display `pedicle_drilling/DrillingDisplay`: the bone specimen's three layers as
 *        translucent boxes, the drilled hole, the residual inner cortical layer and a text
 *        overlay with the recognizer's state, drawn in the `bone` tf frame.
 *
 * Inputs: `simulator/ground_truth` (pedicle_drilling/GroundTruth: layer depths, deepest cut,
 * residual, thrust, breakthrough) and `drilling_state` (pedicle_drilling/DrillingState: state,
 * last key point, averaged force, A*). Both are optional; a missing or broken one only gives a
 * warning or error in the Displays panel, and the rest is still drawn.
 *
 * The specimen is a few centimetres wide and the bit 2.5 mm, which a view of the whole workcell
 * cannot show; the display therefore also draws a magnified "detail" copy of the specimen next
 * to the real one (property "Detail scale", 0 or 1 = off), and puts the text beside it.
 */
#pragma once

#ifndef Q_MOC_RUN
#include <memory>
#include <string>

#include <ros/ros.h>

#include <pedicle_drilling/DrillingState.h>
#include <pedicle_drilling/GroundTruth.h>
#include <rviz/display.h>
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

  /** @brief Drops both messages and clears the drawing (rviz "Reset"). */
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
  void subscribe();
  void unsubscribe();
  void groundTruthCallback(const GroundTruth::ConstPtr& msg);
  void drillingStateCallback(const DrillingState::ConstPtr& msg);
  void rebuild();
  void applyColours();
  std::string overlayText() const;

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

  SpecimenVisual true_scale_;
  SpecimenVisual detail_;
  Ogre::SceneNode* text_node_ = nullptr;
  rviz::MovableText* text_ = nullptr;

  ros::Subscriber ground_truth_sub_;
  ros::Subscriber state_sub_;
  GroundTruth::ConstPtr ground_truth_;
  DrillingState::ConstPtr state_;
  ros::WallTime ground_truth_received_;
  ros::WallTime state_received_;
  std::string layout_error_;
  bool dirty_ = true;
};

}  // namespace rviz_plugins
}  // namespace pedicle_drilling
