/**
 * @file recognizers.cpp
 * @brief Exports the built-in drilling-state recognizers as pluginlib classes of the base class
 *        pedicle_drilling::core::RecognizerInterface (recognizer_plugins.xml): the paper's and
 *        the force-difference baseline. An outside package exports its own the same way.
 */
#include <pluginlib/class_list_macros.hpp>

#include "pedicle_drilling/core/drilling/recognizer_interface.hpp"

PLUGINLIB_EXPORT_CLASS(pedicle_drilling::core::PaperRecognizer,
                       pedicle_drilling::core::RecognizerInterface)
PLUGINLIB_EXPORT_CLASS(pedicle_drilling::core::ForceDifferenceRecognizer,
                       pedicle_drilling::core::RecognizerInterface)
