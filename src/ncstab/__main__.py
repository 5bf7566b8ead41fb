import sys

from ncstab.cli import main

sys.exit(main())
