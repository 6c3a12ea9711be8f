import sys

from viewer.commands.cli import main

sys.exit(main())
