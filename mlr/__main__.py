"""python -m mlr: the learning pipeline's commands (mlr.cli)."""
import sys

from mlr.cli import main

sys.exit(main())
