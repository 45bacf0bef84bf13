from django.urls import re_path

from . import api

DRONE = r"^drones/(?P<drone_id>[A-Za-z0-9_-]{1,64})/video/"

urlpatterns = [
    re_path(DRONE + r"$", api.VideoView.as_view(), name="drone-video"),
    re_path(DRONE + r"whep/$", api.WatchView.as_view(), name="drone-video-watch"),
    re_path(
        DRONE + r"whep/(?P<session>[A-Za-z0-9_-]{1,64})/$",
        api.WatchSessionView.as_view(),
        name="drone-video-session",
    ),
    re_path(DRONE + r"stills/$", api.StillsView.as_view(), name="drone-video-stills"),
    re_path(
        DRONE + r"stills/(?P<pk>[0-9]{1,12})/image/$",
        api.StillImageView.as_view(),
        name="drone-video-still-image",
    ),
    re_path(
        DRONE + r"stills/(?P<pk>[0-9]{1,12})/thumbnail/$",
        api.StillThumbnailView.as_view(),
        name="drone-video-still-thumbnail",
    ),
    re_path(
        DRONE + r"recordings/(?P<pk>[0-9]{1,12})/file/$",
        api.RecordingFileView.as_view(),
        name="drone-video-recording-file",
    ),
    re_path(
        r"^organisations/(?P<slug>[-a-zA-Z0-9_]{1,80})/video-retention/$",
        api.RetentionView.as_view(),
        name="organisation-video-retention",
    ),
    re_path(r"^logs/(?P<pk>[0-9a-f-]{1,36})/video/$", api.LogVideoView.as_view(), name="log-video"),
    re_path(
        r"^flights/(?P<pk>[0-9]{1,12})/video/$", api.FlightVideoView.as_view(), name="flight-video"
    ),
    re_path(
        r"^missions/(?P<pk>[0-9a-f-]{36})/video/$",
        api.MissionVideoView.as_view(),
        name="mission-video",
    ),
]
