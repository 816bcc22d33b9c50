"""artmotion.language"""
