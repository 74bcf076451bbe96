from imubounds.cli import main

raise SystemExit(main())
