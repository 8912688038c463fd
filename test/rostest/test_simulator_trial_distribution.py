#!/usr/bin/python3
"""Scenario check of the Simulator's ~trial_distribution: what simulator/reset draws, and how
bad values are refused."""
import os
import sys
import threading
import unittest

import rospkg
import rospy
import rostest

from pedicle_drilling.msg import VentilatorSettings
from pedicle_drilling.srv import ResetSimulation

NS = '/simulator/trial_distribution/'


class TrialDistributionTest(unittest.TestCase):
    def setUp(self):
        rospy.wait_for_service('/simulator/reset', timeout=30.0)
        self.reset = rospy.ServiceProxy('/simulator/reset', ResetSimulation)
        self.lock = threading.Lock()
        self.settings = []
        rospy.Subscriber('/ventilator/settings', VentilatorSettings, self.on_settings,
                         queue_size=10)

    def on_settings(self, msg):
        with self.lock:
            self.settings.append(msg)

    def test_draws_follow_the_parameters_and_bad_values_are_refused(self):
        # Defaults: the paper's conditions, only the specimen varies.
        res = self.reset(seed=8, moving_bone=True)
        self.assertTrue(res.success, res.message)
        self.assertEqual(res.volunteer_id, 4)
        self.assertEqual(res.patient_amplitude_scale, 1.0)
        self.assertEqual(res.ventilator_rate_bpm, 12.0)
        self.assertEqual(res.ventilator_tidal_volume_ml, 500.0)
        self.assertEqual(res.arm_stiffness_scale, 1.0)
        self.assertAlmostEqual(res.force_noise_sd_n, 0.03, places=12)
        default_inner = res.inner_cortical_thickness_m

        # Spreads and a fixed inner cortex, set between trials.
        rospy.set_param(NS + 'patient/amplitude_scale_sd', 0.2)
        rospy.set_param(NS + 'ventilator/rate_sd_bpm', 3.0)
        rospy.set_param(NS + 'arm/stiffness_scale_sd', 0.2)
        rospy.set_param(NS + 'sensor/noise_scale_sd', 0.3)
        rospy.set_param(NS + 'specimen/inner_cortical_thickness_mean_mm', 3.0)
        rospy.set_param(NS + 'specimen/inner_cortical_thickness_sd_mm', 0.0)
        draws = []
        for seed in (8, 9, 10, 11):
            res = self.reset(seed=seed, moving_bone=True)
            self.assertTrue(res.success, res.message)
            self.assertAlmostEqual(res.inner_cortical_thickness_m, 3.0e-3, places=12)
            self.assertTrue(0.4 <= res.patient_amplitude_scale <= 1.6)
            self.assertTrue(3.0 <= res.ventilator_rate_bpm <= 21.0)
            self.assertTrue(0.4 <= res.arm_stiffness_scale <= 1.6)
            self.assertTrue(0.03 * 0.1 <= res.force_noise_sd_n <= 0.03 * 1.9)
            draws.append((res.patient_amplitude_scale, res.ventilator_rate_bpm,
                          res.arm_stiffness_scale, res.force_noise_sd_n))
        self.assertNotEqual(default_inner, 3.0e-3)
        for k in range(4):
            self.assertGreater(len({d[k] for d in draws}), 1, 'factor %d never varies' % k)
        # The same seed draws the same trial.
        again = self.reset(seed=11, moving_bone=True)
        self.assertEqual((again.patient_amplitude_scale, again.ventilator_rate_bpm,
                          again.arm_stiffness_scale, again.force_noise_sd_n), draws[-1])

        # The drawn breathing rate is what the ventilator publishes from the next breath on.
        deadline = rospy.Time.now() + rospy.Duration(20.0)
        seen = False
        while rospy.Time.now() < deadline and not seen:
            with self.lock:
                seen = any(abs(s.rate_bpm - again.ventilator_rate_bpm) < 1e-9
                           for s in self.settings)
            rospy.sleep(0.1)
        self.assertTrue(seen, 'ventilator/settings never showed rate %.3f'
                        % again.ventilator_rate_bpm)

        # Out of range: refused, naming the parameter (the core test checks nothing changes).
        rospy.set_param(NS + 'patient/amplitude_scale_sd', 0.9)
        res = self.reset(seed=12, moving_bone=True)
        self.assertFalse(res.success)
        self.assertIn(NS + 'patient/amplitude_scale_sd', res.message)
        self.assertIn('nothing was reset', res.message)
        rospy.set_param(NS + 'patient/amplitude_scale_sd', 0.2)
        # Unknown key (a typo would otherwise be a silent default).
        rospy.set_param(NS + 'arm/stifness_scale_sd', 0.1)
        res = self.reset(seed=12, moving_bone=True)
        self.assertFalse(res.success)
        self.assertIn(NS + 'arm/stifness_scale_sd', res.message)
        rospy.delete_param(NS + 'arm/stifness_scale_sd')
        # Not a number.
        rospy.set_param(NS + 'ventilator/rate_sd_bpm', 'fast')
        res = self.reset(seed=12, moving_bone=True)
        self.assertFalse(res.success)
        self.assertIn(NS + 'ventilator/rate_sd_bpm', res.message)
        rospy.set_param(NS + 'ventilator/rate_sd_bpm', 3.0)
        res = self.reset(seed=12, moving_bone=True)
        self.assertTrue(res.success, res.message)

    def test_bone_plays_a_model_file_on_the_paper_bench(self):
        model = os.path.join(rospkg.RosPack().get_path('pedicle_drilling'), 'config',
                             'patient_default.yaml')
        rospy.set_param('/simulator/bone_motion_model_path', model)
        try:
            res = self.reset(seed=5, moving_bone=True)
            self.assertTrue(res.success, res.message)
            self.assertIn('the bone plays the model', res.message)
            # A missing file refuses the reset, naming the parameter and the file.
            rospy.set_param('/simulator/bone_motion_model_path', '/nonexistent/model.yaml')
            res = self.reset(seed=5, moving_bone=True)
            self.assertFalse(res.success)
            self.assertIn('bone_motion_model_path', res.message)
            self.assertIn('/nonexistent/model.yaml', res.message)
            self.assertIn('nothing was reset', res.message)
        finally:
            rospy.set_param('/simulator/bone_motion_model_path', '')
        res = self.reset(seed=5, moving_bone=True)
        self.assertTrue(res.success, res.message)
        self.assertNotIn('plays the model', res.message)

    def test_reset_with_an_explicit_specimen(self):
        # Layer thicknesses given in the request; 0 leaves a layer to the seed's draw.
        drawn = self.reset(seed=21, moving_bone=False)
        self.assertTrue(drawn.success, drawn.message)
        res = self.reset(seed=21, moving_bone=False, outer_cortical_thickness_mm=1.5,
                         cancellous_thickness_mm=0.0, inner_cortical_thickness_mm=2.6)
        self.assertTrue(res.success, res.message)
        self.assertAlmostEqual(res.outer_cortical_thickness_m, 1.5e-3, places=12)
        self.assertAlmostEqual(res.inner_cortical_thickness_m, 2.6e-3, places=12)
        # The cancellous layer is drawn from the seed: the same request draws it again.
        same = self.reset(seed=21, moving_bone=False, outer_cortical_thickness_mm=1.5,
                          inner_cortical_thickness_mm=2.6)
        self.assertEqual(same.cancellous_thickness_m, res.cancellous_thickness_m)
        self.assertGreaterEqual(res.cancellous_thickness_m, 0.8e-3)
        # The next plain reset draws again (the request does not stick).
        again = self.reset(seed=21, moving_bone=False)
        self.assertAlmostEqual(again.outer_cortical_thickness_m, drawn.outer_cortical_thickness_m,
                               places=12)
        # Thinner than the minimum layer, negative or NaN: refused, naming the field.
        for value in (0.5, -1.0, float('nan'), 150.0):
            res = self.reset(seed=22, moving_bone=False, inner_cortical_thickness_mm=value)
            self.assertFalse(res.success, value)
            self.assertIn('inner_cortical_thickness_mm', res.message)
            self.assertIn('nothing was reset', res.message)

    def test_time_zero_sets_the_trials_stamps(self):
        # ResetSimulation.time_zero: kept when ahead of the present and on the 0.1 s grid (a
        # campaign gives a trial the same stamps in every run); one behind the present falls back
        # to the next 0.1 s; one off the grid is refused, naming the field.
        plain = self.reset(seed=31, moving_bone=False)
        self.assertTrue(plain.success, plain.message)
        self.assertEqual(plain.reset_time.nsecs % 100000000, 0)
        ahead = rospy.Time(plain.reset_time.secs + 1000, plain.reset_time.nsecs)
        res = self.reset(seed=31, moving_bone=False, time_zero=ahead)
        self.assertTrue(res.success, res.message)
        self.assertEqual(res.reset_time, ahead)
        behind = self.reset(seed=31, moving_bone=False, time_zero=rospy.Time(1))
        self.assertTrue(behind.success, behind.message)
        self.assertGreater(behind.reset_time, ahead)
        self.assertEqual(behind.reset_time.nsecs % 100000000, 0)
        off_grid = rospy.Time(behind.reset_time.secs + 1000, 50000000)
        res = self.reset(seed=31, moving_bone=False, time_zero=off_grid)
        self.assertFalse(res.success)
        self.assertIn('time_zero', res.message)
        self.assertIn('nothing was reset', res.message)


if __name__ == '__main__':
    rospy.init_node('test_simulator_trial_distribution')
    rostest.rosrun('pedicle_drilling', 'simulator_trial_distribution', TrialDistributionTest,
                   sys.argv)
