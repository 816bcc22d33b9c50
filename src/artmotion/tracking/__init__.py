"""artmotion.tracking"""
