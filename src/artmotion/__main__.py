from artmotion.cli import run

run()
