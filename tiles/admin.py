"""Importing a tile set from the admin: upload an MBTiles file or a ZIP of a z/x/y folder
(at most TILES_UPLOAD_MAX_BYTES, from a user the admin lets add tile sets: checked before
the body is read, config/uploadgate.py); it is checked completely, within the import
limits of tiles/sources.py, before anything is kept."""

from __future__ import annotations

import uuid
from pathlib import Path

from django import forms
from django.conf import settings
from django.contrib import admin

from tiles import importer, sources, store
from tiles.models import TileSet
from tiles.store import TileError

# The admin's upload form posts here; config/asgi.py refuses strangers and bodies over the
# limit at once.
TILE_UPLOAD_PATH = "/admin/tiles/tileset/add/"


def tile_upload_limit() -> int:
    return int(settings.TILES_UPLOAD_MAX_BYTES)


class TileSetUploadForm(forms.ModelForm):
    file = forms.FileField(help_text="An .mbtiles file, or a .zip of <z>/<x>/<y>.png tiles.")
    scheme = forms.ChoiceField(
        choices=[("xyz", "XYZ (row 0 at the north)"), ("tms", "TMS (row 0 at the south)")],
        initial="xyz",
        help_text="Only for ZIPs of folders; MBTiles files are always TMS, as the spec says.",
    )

    class Meta:
        model = TileSet
        fields = ("name", "attribution")

    def __init__(self, *args, **kwargs) -> None:  # type: ignore[no-untyped-def]
        super().__init__(*args, **kwargs)
        self.fields["name"].required = False
        self.staged: importer.Staged | None = None

    def clean(self) -> dict:
        data = super().clean()
        upload = data.get("file")
        if upload is None:
            return data
        limit = tile_upload_limit()
        if upload.size > limit:
            raise forms.ValidationError(f"The file is larger than the limit of {limit} bytes.")
        on_disk = hasattr(upload, "temporary_file_path")
        path = Path(upload.temporary_file_path()) if on_disk else _spool(upload)
        try:
            self.staged = importer.stage(sources.open_source(path, data.get("scheme", "xyz")))
        except TileError as exc:
            raise forms.ValidationError(str(exc)) from exc
        finally:
            if not on_disk:
                path.unlink(missing_ok=True)
        return data


def _spool(upload) -> Path:  # type: ignore[no-untyped-def]
    """Small uploads stay in memory; SQLite needs a file."""
    folder = store.root() / "incoming"
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"upload-{uuid.uuid4().hex}"
    with path.open("wb") as out:
        for chunk in upload.chunks():
            out.write(chunk)
    return path


@admin.register(TileSet)
class TileSetAdmin(admin.ModelAdmin):
    list_display = ("name", "min_zoom", "max_zoom", "tile_count", "size_bytes", "created_at")
    readonly_fields = (
        "source", "min_zoom", "max_zoom", "west", "south", "east", "north",
        "tile_count", "size_bytes", "created_at",
    )  # fmt: skip

    def get_form(self, request, obj=None, change=False, **kwargs):  # type: ignore[no-untyped-def]
        if obj is None:
            kwargs["form"] = TileSetUploadForm
        return super().get_form(request, obj, change, **kwargs)

    def get_readonly_fields(self, request, obj=None):  # type: ignore[no-untyped-def]
        return self.readonly_fields if obj is not None else ()

    def get_fields(self, request, obj=None):  # type: ignore[no-untyped-def]
        if obj is None:
            return ("file", "scheme", "name", "attribution")
        return ("name", "attribution", *self.readonly_fields)

    def save_model(self, request, obj, form, change) -> None:  # type: ignore[no-untyped-def]
        staged = getattr(form, "staged", None)
        if change or staged is None:
            super().save_model(request, obj, form, change)
            return
        tileset = importer.commit(staged, obj.name, form.cleaned_data["file"].name, obj.attribution)
        obj.pk = tileset.pk
        obj.__dict__.update(TileSet.objects.filter(pk=tileset.pk).values()[0])
        obj._state.adding = False

    def delete_model(self, request, obj) -> None:  # type: ignore[no-untyped-def]
        importer.delete_tiles(obj)
        super().delete_model(request, obj)

    def delete_queryset(self, request, queryset) -> None:  # type: ignore[no-untyped-def]
        for tileset in queryset:
            importer.delete_tiles(tileset)
        super().delete_queryset(request, queryset)
