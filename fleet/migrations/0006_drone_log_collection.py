from django.db import migrations, models


class Migration(migrations.Migration):
    dependencies = [
        ("fleet", "0005_remote_id_identity"),
    ]

    operations = [
        migrations.AddField(
            model_name="drone",
            name="log_collection",
            field=models.CharField(
                choices=[
                    ("always", "Always"),
                    ("ground_links", "Only on Wi-Fi or ground links"),
                    ("off", "Off"),
                ],
                db_default="always",
                default="always",
                max_length=16,
            ),
        ),
    ]
