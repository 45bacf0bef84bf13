import django.db.models.deletion
from django.db import migrations, models


class Migration(migrations.Migration):
    dependencies = [
        ("fleet", "0005_remote_id_identity"),
        ("livevideo", "0002_videorecording"),
    ]

    operations = [
        migrations.CreateModel(
            name="VideoRetention",
            fields=[
                (
                    "id",
                    models.BigAutoField(
                        auto_created=True, primary_key=True, serialize=False, verbose_name="ID"
                    ),
                ),
                ("keep_days", models.PositiveIntegerField(blank=True, null=True)),
                ("max_bytes", models.PositiveBigIntegerField(blank=True, null=True)),
                (
                    "organisation",
                    models.OneToOneField(
                        on_delete=django.db.models.deletion.CASCADE,
                        related_name="video_retention",
                        to="fleet.organisation",
                    ),
                ),
            ],
        ),
    ]
