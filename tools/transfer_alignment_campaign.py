"""Transfer-alignment campaigns and the bending table (docs/transfer_alignment.md).

The command line of :mod:`strapdown_ros.stages.transfer_montecarlo`, e.g.
``python tools/transfer_alignment_campaign.py config/scenarios/transfer_alignment.yaml --runs 50``.
"""

import sys

from strapdown_ros.stages.transfer_montecarlo import main

if __name__ == "__main__":
    sys.exit(main())
