"""python -m voice: the voice and keyboard assistant's commands (voice.cli)."""
import sys

from voice.cli import main

sys.exit(main())
