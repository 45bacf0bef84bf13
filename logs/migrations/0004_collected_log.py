import uuid

import django.db.models.deletion
from django.db import migrations, models


class Migration(migrations.Migration):
    dependencies = [
        ("logs", "0003_drone_figures_references"),
        ("fleet", "0001_initial"),
    ]

    operations = [
        migrations.CreateModel(
            name="CollectedLog",
            fields=[
                (
                    "id",
                    models.UUIDField(
                        default=uuid.uuid4, editable=False, primary_key=True, serialize=False
                    ),
                ),
                (
                    "kind",
                    models.CharField(
                        choices=[
                            ("onboard", "Onboard recording"),
                            ("fc", "Flight controller's log"),
                        ],
                        max_length=8,
                    ),
                ),
                ("name", models.CharField(max_length=255)),
                ("size", models.BigIntegerField()),
                ("sha256", models.CharField(max_length=64)),
                ("received", models.BigIntegerField(default=0)),
                ("flight_started_at", models.DateTimeField()),
                ("flight_ended_at", models.DateTimeField()),
                ("created_at", models.DateTimeField(auto_now_add=True)),
                ("completed_at", models.DateTimeField(blank=True, null=True)),
                (
                    "drone",
                    models.ForeignKey(
                        on_delete=django.db.models.deletion.CASCADE,
                        related_name="collected_logs",
                        to="fleet.drone",
                    ),
                ),
                (
                    "log",
                    models.OneToOneField(
                        blank=True,
                        null=True,
                        on_delete=django.db.models.deletion.SET_NULL,
                        related_name="collected",
                        to="logs.flightlog",
                    ),
                ),
                (
                    "organisation",
                    models.ForeignKey(
                        on_delete=django.db.models.deletion.CASCADE,
                        related_name="+",
                        to="fleet.organisation",
                    ),
                ),
            ],
            options={
                "ordering": ["flight_started_at", "kind"],
                "indexes": [
                    models.Index(fields=["drone", "flight_started_at"], name="log_collected_flight")
                ],
                "constraints": [
                    models.UniqueConstraint(
                        fields=("drone", "kind", "sha256"), name="logs_collected_once"
                    )
                ],
            },
        ),
    ]
