import sys

from mimarble.cli.main import main

sys.exit(main())
