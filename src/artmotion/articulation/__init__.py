"""artmotion.articulation"""
