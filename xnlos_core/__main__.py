"""``python -m xnlos_core`` runs the xnlos command line."""
import sys

from .cli import main

sys.exit(main())
