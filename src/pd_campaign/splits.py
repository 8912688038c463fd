"""A split of the labelled dataset (doc/dataset.md) as pandas tables, for the API
(pd_campaign.api.load_split) and for a submitted entry's training (pd_campaign.submission)."""
import json
import os

import numpy as np
import pandas

from . import dataset


class SplitError(ValueError):
    """A split or dataset folder that is not one, named."""


class Split:
    """A split of a campaign_dataset folder (doc/dataset.md): `samples` (one row per
    force-sensor sample: dataset.SAMPLE_COLUMNS and `trial`, the trial's row in `trials`),
    `trials` (the trial table, dataset.TRIAL_FIELDS' columns), `meta` (split.json's), `path`
    (the .npz, which the offline tools read)."""

    def __init__(self, dataset_dir, name):
        if name not in dataset.SPLITS:
            raise SplitError('split: %r is not one of %s' % (name, ', '.join(dataset.SPLITS)))
        self.dataset, self.name = os.path.abspath(str(dataset_dir)), name
        self.path = os.path.join(self.dataset, '%s.npz' % name)
        try:
            with open(os.path.join(self.dataset, 'split.json')) as handle:
                self.meta = json.load(handle).get('meta') or {}
            with np.load(self.path) as z:
                columns = {key: z[key] for key in z.files}
        except (OSError, ValueError) as error:
            raise SplitError('dataset: %s is not a campaign_dataset folder (%s)' % (
                self.dataset, error)) from None
        self.samples = pandas.DataFrame({key: columns[key] for key in
                                         dataset.SAMPLE_COLUMNS + ['trial']})
        self.trials = pandas.DataFrame({key[len('trial_'):]: value
                                        for key, value in columns.items()
                                        if key.startswith('trial_')})

    def trial(self, k):
        """The samples of the k-th trial of `trials`."""
        return self.samples[self.samples['trial'] == k]
