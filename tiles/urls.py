from django.urls import path

from tiles import views

app_name = "tiles"

urlpatterns = [
    path("<int:z>/<int:x>/<int:y>.<str:ext>", views.tile, name="tile"),
]
