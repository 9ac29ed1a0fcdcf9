"""Moving obstacles and the situation "obstacle overcoming": the obstacles and the traffic they
make (`moving`), deciding among alternatives within the time stock a critical event leaves
(`overcoming`), the situation as a schema of anytime modules (`overcoming_modules`), and
crossing the map among the obstacles (`crossing`)."""
