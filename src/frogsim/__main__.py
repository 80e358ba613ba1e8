"""``python -m frogsim`` runs the command-line interface."""
import sys

from frogsim.cli import main

sys.exit(main())
