import sys

from lotsen.cli.main import main

sys.exit(main())
