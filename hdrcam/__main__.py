import sys

from hdrcam.cli import main

sys.exit(main())
