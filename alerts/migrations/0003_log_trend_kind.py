from django.db import migrations, models


class Migration(migrations.Migration):
    dependencies = [
        ("alerts", "0002_remote_id_kind"),
    ]

    operations = [
        migrations.AlterField(
            model_name="alert",
            name="kind",
            field=models.CharField(
                choices=[
                    ("critical_alarm", "Critical alarm"),
                    ("replacement", "Drone replaced"),
                    ("drone_lost", "Drone lost"),
                    ("mission_completed", "Mission completed"),
                    ("mission_failed", "Mission failed"),
                    ("remote_id", "Remote ID failing"),
                    ("log_trend", "Flight log figure drifting"),
                ],
                max_length=20,
            ),
        ),
    ]
