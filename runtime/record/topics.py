"""What a recording holds: its channels' topics, the attachment names and the frames of its
transforms. The writer (:mod:`.telemetry`) and the reader (:mod:`.reader`) share them."""

TOPIC_IMAGE = "/camera/image"
TOPIC_RAW = "/camera/raw"
TOPIC_FRAME = "/percept/frame"
TOPIC_JOINTS = "/joints"
TOPIC_TF = "/tf"
TOPIC_WORLD = "/percept/world"
TOPIC_BOXES = "/percept/boxes"
TOPIC_STATUS = "/percept/status"
TOPIC_SCENE = "/scene"
LIVE_ONLY_PREFIX = "/live/"  # debug images and the map: shown live, never recorded

BACKGROUND_ATTACHMENT = "background.npz"
GROUND_FRAME = "ground"
CAMERA_FRAME = "camera"
