"""python3 -m pd_campaign.sensitivity: campaign_sensitivity."""
import sys

from .command import main

sys.exit(main())
