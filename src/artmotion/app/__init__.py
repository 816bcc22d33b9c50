"""artmotion.app"""
