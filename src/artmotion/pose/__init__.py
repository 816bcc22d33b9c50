"""artmotion.pose"""
