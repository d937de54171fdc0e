"""``python -m animcodec.sweep CORPUS_DIR ... [--scheduler tcp://host:8786]``: a corpus
rate-distortion sweep on a Dask cluster (see :mod:`animcodec.distributed`).

``animcodec.sweep`` the attribute is the function :func:`animcodec.distributed.sweep`; this
module is the command-line entry only.
"""

import sys

from animcodec.distributed import main

if __name__ == "__main__":
    sys.exit(main())
