"""Baseline drilling-state recognizers for the labelled force dataset (doc/dataset.md),
written against the Python recognizer contract of pd_campaign.recognizers, and the offline
harness that scores any recognizer on the dataset with the very objects the closed loop runs.

- ``offline_stop`` / ``evaluate_offline``: push a trial's raw samples, in order, through a
  recognizer (reset first, one Python call per sample, exactly as the C++ side does) and read the
  dataset's label at the first sample whose output says ``stop``: correct (inner cortical),
  early (air, outer cortical, cancellous), late (canal: broken through) or none.
- ``tune``: a grid search on the training split, the best few re-scored on the validation
  split, the best of those chosen.
- ``ChangePointRecognizer``: Bayesian online change-point detection (Adams and MacKay 2007) on
  the logarithm of block means, with a segment logic on relative levels.
- ``GaussianProcessRecognizer``, ``ForceDropRecognizer``: an online Gaussian-process detector
  and a transient force-drop detector (pd_campaign.detectors, the two 2026 baselines).
- ``LearnedRecognizer``: a small classifier (gradient-boosted trees or logistic regression,
  fitted with scikit-learn by ``train_learned``) exported to JSON and evaluated in plain Python.

Command line::

    python3 -m pd_campaign.baselines train --train train.npz --validation validation.npz \\
        --out model.json [--seed 0] [--kind gradient_boosting|logistic]
    python3 -m pd_campaign.baselines evaluate --data validation.npz \\
        --recognizer pd_campaign.baselines.ChangePointRecognizer [--param name=value ...]
    python3 -m pd_campaign.baselines tune \\
        --recognizer pd_campaign.recognizers.ThresholdRecognizer --train train.npz \\
        --validation validation.npz --grid cortical_n=2.0,2.2 --grid confirm=1,2 [--keep 5]

Never choose anything on the test split: tune on train, select on validation."""
import argparse
import importlib
import json
import sys

# The baselines by their documented paths (python:pd_campaign.baselines.<Class>, the model
# format, config/leaderboard.yaml): each lives in its own module.
from pd_campaign.change_point import ChangePointRecognizer, RunLengthPosterior  # noqa: F401
from pd_campaign.detectors import ForceDropRecognizer, GaussianProcessRecognizer  # noqa: F401
from pd_campaign.learned import (FEATURES, LearnedModel, LearnedRecognizer,  # noqa: F401
                                 train_learned)
from pd_campaign.offline import configured, evaluate_offline, tune


# --- command line ---------------------------------------------------------------------------

def load_class(name):
    """The class named <module>.<Class> (a leading python: is allowed)."""
    name = name[len('python:'):] if name.startswith('python:') else name
    module, _, cls = name.rpartition('.')
    if not module:
        raise ValueError('recognizer: expected <module>.<Class>, got %r' % name)
    return getattr(importlib.import_module(module), cls)


def _pairs(items, what):
    out = {}
    for item in items or []:
        name, sep, value = item.partition('=')
        if not sep or not name:
            raise ValueError('%s: expected name=value, got %r' % (what, item))
        out[name] = value
    return out


def main(argv=None):
    parser = argparse.ArgumentParser(prog='python3 -m pd_campaign.baselines',
                                     description=__doc__.split('\n\n')[0])
    commands = parser.add_subparsers(dest='command', required=True)
    train = commands.add_parser('train', help='fit LearnedRecognizer\'s model')
    train.add_argument('--train', required=True)
    train.add_argument('--validation', required=True)
    train.add_argument('--out', required=True)
    train.add_argument('--seed', type=int, default=0)
    train.add_argument('--kind', default='gradient_boosting',
                       choices=('gradient_boosting', 'logistic'))
    train.add_argument('--features', default=','.join(FEATURES),
                       help='comma-separated features of the model (default: all: %(default)s)')
    evaluate = commands.add_parser('evaluate', help='offline stops of a recognizer on a split')
    evaluate.add_argument('--data', required=True)
    evaluate.add_argument('--recognizer', required=True)
    evaluate.add_argument('--param', action='append', metavar='NAME=VALUE')
    tuning = commands.add_parser('tune', help='grid search on train, chosen on validation')
    tuning.add_argument('--recognizer', required=True)
    tuning.add_argument('--train', required=True)
    tuning.add_argument('--validation', required=True)
    tuning.add_argument('--grid', action='append', required=True, metavar='NAME=V1,V2,...')
    tuning.add_argument('--param', action='append', metavar='NAME=VALUE',
                        help='fixed settings beside the grid')
    tuning.add_argument('--keep', type=int, default=5)
    args = parser.parse_args(argv)
    try:
        if args.command == 'train':
            spec = train_learned(args.train, args.validation, args.out, seed=args.seed,
                                 kind=args.kind, features=args.features.split(','))
            result = {'threshold': spec['threshold'], 'confirm': spec['confirm'],
                      'validation': spec['training']['validation_counts']}
        elif args.command == 'evaluate':
            cls, settings = load_class(args.recognizer), _pairs(args.param, 'param')
            result, _ = evaluate_offline(lambda: configured(cls, settings), args.data)
        else:
            cls, fixed = load_class(args.recognizer), _pairs(args.param, 'param')
            grid = {name: values.split(',')
                    for name, values in _pairs(args.grid, 'grid').items()}
            grid.update({name: [value] for name, value in fixed.items()})
            result = tune(cls, grid, args.train, args.validation, keep=args.keep)
            del result['train']
    except ValueError as e:
        sys.stderr.write('pd_campaign.baselines: %s\n' % e)
        return 2
    json.dump(result, sys.stdout, indent=1)
    sys.stdout.write('\n')
    return 0


if __name__ == '__main__':
    sys.exit(main())
