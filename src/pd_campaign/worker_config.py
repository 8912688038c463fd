"""The --engine ros worker's pipeline settings: the nodelets' parameter files with the campaign's
class parameters (plugin_config, as text the classes read) and the pipeline launch's
arguments (launch_arguments)."""
import os

from pd_campaign.atomic import atomic_write

PAPER_CLASSES = {'recognizer': 'pedicle_drilling/PaperRecognizer',
                 'compensator': 'pedicle_drilling/PaperCompensator'}
NODE_CONFIGS = {'recognizer': 'recognizer.yaml', 'compensator': 'compensation_planner.yaml'}
# The StateRecognizer's own settings in recognizer.yaml, no parameter of the recognizer class;
# its sensor_rate_hz is the simulated sensor's (launch_arguments: force_rate_hz).
NODE_ONLY_SETTINGS = ('axis', 'queue_size', 'rate_tolerance', 'rate_window_s', 'sensor_rate_hz')


def plugin_config(kind, class_name, settings, package_root, out_path):
    """The nodelet's parameter file with a class's NAME=VALUE settings (campaign
    --recognizer-param / --compensator-param, as the core engine takes them), written to
    `out_path`; None when there are none (the launch then loads the package's file). Every
    class gets them as text in ~recognizer_params / ~compensator_params and reads them itself,
    as in the core engine (the paper recognizer with its ParamTable); a paper recognizer's
    setting leaves the node's own key of the package file (~window, ...): the node refuses a
    parameter given both ways. ValueError naming a setting the nodelet would not take (the
    paper compensator has none; the node's own settings are not the recognizer's)."""
    if not settings:
        return None
    import yaml
    with open(os.path.join(package_root, 'config', NODE_CONFIGS[kind])) as handle:
        config = yaml.safe_load(handle) or {}
    pairs = []
    for item in settings:
        name, sep, value = item.partition('=')
        if not sep or not name:
            raise ValueError('--%s-param %r is not NAME=VALUE' % (kind, item))
        pairs.append((name, value))
    if class_name == PAPER_CLASSES[kind]:
        for name, _ in pairs:
            if kind != 'recognizer' or name not in config or name in NODE_ONLY_SETTINGS:
                raise ValueError('--%s-param %s: not a parameter of %s' % (kind, name, class_name))
            del config[name]  # given once, in ~recognizer_params
    config[kind + '_params'] = dict(pairs)
    with atomic_write(out_path) as handle:
        yaml.safe_dump(config, handle, default_flow_style=False)
    return out_path


def launch_arguments(args):
    """The pipeline launch's NAME:=VALUE arguments of a worker (besides the nodelets' parameter
    files). roslaunch takes an argument the launch file does not declare without a word:
    test_worker_config checks each against campaign_pipeline.launch. A simulated sensor rate
    (--simulator-param force_sensor_rate_hz) is the launch's force_rate_hz: the recognizer and
    the monitor are declared at it, as the core engine declares it to its recognizer."""
    rates = [setting.split('=', 1)[1] for setting in getattr(args, 'simulator_param', None) or ()
             if setting.split('=', 1)[0] == 'force_sensor_rate_hz']
    return ['patient_model:=%s' % args.default_model,
            'real_time_factor:=%g' % args.real_time_factor,
            'clock_period_ms:=%d' % (10 if args.bags else 100),
            'segment_profile:=%s' % args.segment_profile,
            'depth_limit:=%s' % args.depth_limit,
            'recognizer:=%s' % args.recognizer, 'compensator:=%s' % args.compensator,
            # ~identify writes only there (the trials' models, model_path below)
            'model_folder:=%s' % os.path.abspath(os.path.join(args.out, 'models'))] + [
                'force_rate_hz:=%s' % rate for rate in rates[-1:]]
