/**
 * @file load_plugins.cpp
 * @brief Loads every class the package exports through pluginlib, by base class, constructs
 *        and destroys one object of each, and prints "loaded <base> <class>" or
 *        "FAILED <base> <class>: <why>" (test_plugin_classes.py checks the list against the
 *        package's plugin XML files). The rviz classes need a QApplication (offscreen) and the
 *        ROS node this runs as (their NodeHandles).
 */
#include <pluginlib/class_loader.hpp>

#include <QApplication>

#include <iostream>
#include <string>

#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <rviz/display.h>
#include <rviz/panel.h>

#include "pedicle_drilling/core/control/compensator_interface.hpp"
#include "pedicle_drilling/core/drilling/recognizer_interface.hpp"

namespace {

/** @brief Loads every class of `base` declared by pedicle_drilling's XML; returns failures. */
template <class Base>
int loadAll(const std::string& package, const std::string& base) {
  int failures = 0;
  pluginlib::ClassLoader<Base> loader(package, base);
  for (const std::string& name : loader.getDeclaredClasses()) {
    if (loader.getClassPackage(name) != "pedicle_drilling") continue;  // others' classes
    try {
      Base* object = loader.createUnmanagedInstance(name);
      delete object;
      std::cout << "loaded " << base << " " << name << std::endl;
    } catch (const std::exception& e) {
      std::cout << "FAILED " << base << " " << name << ": " << e.what() << std::endl;
      ++failures;
    }
  }
  return failures;
}

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "load_plugins", ros::init_options::AnonymousName);
  ros::NodeHandle nh;
  QApplication app(argc, argv);
  int failures = 0;
  failures += loadAll<nodelet::Nodelet>("nodelet", "nodelet::Nodelet");
  failures += loadAll<rviz::Display>("rviz", "rviz::Display");
  failures += loadAll<rviz::Panel>("rviz", "rviz::Panel");
  failures += loadAll<pedicle_drilling::core::RecognizerInterface>(
      "pedicle_drilling", "pedicle_drilling::core::RecognizerInterface");
  failures += loadAll<pedicle_drilling::core::CompensatorInterface>(
      "pedicle_drilling", "pedicle_drilling::core::CompensatorInterface");
  return failures == 0 ? 0 : 1;
}
