"""Speech: bookmarked text, the espeak-ng synthesizer, phonemes and visemes."""
