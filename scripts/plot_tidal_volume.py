#!/usr/bin/python3
"""Plots the CSV of `rosrun pedicle_drilling tidal_volume` (t,flow,volume) to a PNG."""
import csv
import sys

import matplotlib
matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402

from pd_campaign.atomic import atomic_savefig  # noqa: E402


def main(csv_path, png_path):
    t, flow, volume = [], [], []
    with open(csv_path) as handle:
        for row in csv.DictReader(handle):
            t.append(float(row['t']))
            flow.append(float(row['flow']))
            volume.append(float(row['volume']))
    fig, (ax_flow, ax_volume) = plt.subplots(2, 1, sharex=True, figsize=(8, 5))
    ax_flow.plot(t, flow, color='tab:blue')
    ax_flow.axhline(0.0, color='grey', linewidth=0.5)
    ax_flow.set_ylabel('flow F(t) [ml/s]')
    ax_volume.plot(t, volume, color='tab:red')
    ax_volume.set_ylabel('tidal volume Tv(t) [ml]')
    ax_volume.set_xlabel('t [s]')
    fig.suptitle('Ventilator: volume control, square inspiration, exponential expiration')
    fig.tight_layout()
    try:
        atomic_savefig(fig, png_path, dpi=110)
    finally:
        plt.close(fig)


if __name__ == '__main__':
    main(sys.argv[1], sys.argv[2])
