from artmotion.cli import main

raise SystemExit(main())
