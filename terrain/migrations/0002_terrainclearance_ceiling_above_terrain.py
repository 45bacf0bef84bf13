from django.db import migrations, models


class Migration(migrations.Migration):
    dependencies = [
        ("terrain", "0001_initial"),
    ]

    operations = [
        migrations.AddField(
            model_name="terrainclearance",
            name="ceiling_above_terrain",
            field=models.BooleanField(
                default=False,
                help_text=(
                    "Also read the envelope's maximum height above the terrain wherever it is "
                    "imported (the maximum above home still holds)."
                ),
            ),
        ),
    ]
