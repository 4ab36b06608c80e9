"""``python -m xnlos_core`` runs the xnlos command line."""
import sys

from xnlos_core.app.cli import main

sys.exit(main())
