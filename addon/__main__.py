"""`python -m addon` runs the same command line as the `omniwarp` script."""
import sys

from .launch import main

sys.exit(main())
