import django.db.models.deletion
from django.db import migrations, models


class Migration(migrations.Migration):
    dependencies = [
        ("airspace", "0001_initial"),
        ("fleet", "0004_command_sent_at_by_sender"),
    ]

    operations = [
        migrations.CreateModel(
            name="LandingSlot",
            fields=[
                (
                    "id",
                    models.BigAutoField(
                        auto_created=True, primary_key=True, serialize=False, verbose_name="ID"
                    ),
                ),
                ("site_lat", models.FloatField()),
                ("site_lon", models.FloatField()),
                ("layer_m", models.FloatField(help_text="Holding height above home.")),
                (
                    "state",
                    models.CharField(
                        choices=[("holding", "Holding"), ("landing", "Landing")], max_length=10
                    ),
                ),
                ("joined_at", models.DateTimeField(auto_now_add=True)),
                ("landing_at", models.DateTimeField(blank=True, null=True)),
                ("ended_at", models.DateTimeField(blank=True, null=True)),
                ("end_reason", models.CharField(blank=True, max_length=80)),
                (
                    "drone",
                    models.ForeignKey(
                        on_delete=django.db.models.deletion.CASCADE,
                        related_name="landing_slots",
                        to="fleet.drone",
                    ),
                ),
                (
                    "organisation",
                    models.ForeignKey(
                        on_delete=django.db.models.deletion.CASCADE,
                        related_name="landing_slots",
                        to="fleet.organisation",
                    ),
                ),
            ],
            options={
                "indexes": [
                    models.Index(
                        condition=models.Q(("ended_at__isnull", True)),
                        fields=["organisation", "joined_at"],
                        name="airspace_landing_active",
                    )
                ],
            },
        ),
    ]
