"""``python -m akf`` runs the ``akf`` command."""
import sys

from .cli import main

sys.exit(main())
