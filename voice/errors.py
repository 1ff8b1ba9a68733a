"""The errors a user can cause or fix (a bad file, no microphone, no network, no ground station):
the command line prints their message and exits with status 2 instead of a traceback."""
from voice.audio import AudioError, NoAudioDevice
from voice.backend import BackendError
from voice.stt import RecognitionError

USER_ERRORS = (AudioError, NoAudioDevice, BackendError, RecognitionError)
