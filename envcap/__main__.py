"""python -m envcap"""
import sys

from envcap.cli import main

sys.exit(main())
