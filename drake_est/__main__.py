import sys

from drake_est.cli import main

sys.exit(main())
