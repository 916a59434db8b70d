import sys

from sieve_mi.cli import main

sys.exit(main())
